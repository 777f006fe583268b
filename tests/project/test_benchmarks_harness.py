"""The benchmarks' harness: benchmarks.run writes each module's figures between its own markers in BENCHMARKS.md
and keeps every byte outside them (the notes written by hand), whatever order the modules run in; a child process
measures its own peak memory, not its parent's."""

import resource
import subprocess
import sys
import types

import numpy as np
import pytest

from benchmarks import run
from benchmarks.common import CHILD_PEAK_BYTES

NOTES = "# Benchmarks\n\nA note by hand.\n\n{a}\n\nWhat was tried for a: x, y.\n\n{b}\nTrailing note, no newline"


def _block(name: str, body: str) -> str:
    return f"{run.begin(name)}\n{body}\n{run.end(name)}"


def _outside(text: str, names) -> str:
    """The text with every named block cut out."""
    for name in names:
        first, last = text.index(run.begin(name)), text.index(run.end(name)) + len(run.end(name))
        text = text[:first] + text[last:]
    return text


def test_a_block_is_replaced_and_every_byte_outside_it_kept():
    text = NOTES.format(a=_block("bench_a", "### A\n\nold figures"), b=_block("bench_b", "### B\n\nb's"))
    out = run.splice(text, "bench_a", "### A\n\nnew figures\n")
    assert "new figures" in out and "old figures" not in out and "b's" in out
    assert _outside(out, ["bench_a", "bench_b"]) == _outside(text, ["bench_a", "bench_b"])
    assert run.splice(out, "bench_a", "### A\n\nold figures") == text  # and back again


def test_a_module_without_a_block_gets_one_at_the_end():
    text = NOTES.format(a="", b="")
    out = run.splice(text, "bench_new", "### New\n\nfigures")
    assert out.startswith(text.rstrip()) and out.endswith(_block("bench_new", "### New\n\nfigures") + "\n")


@pytest.mark.parametrize("broken", ["{open}\nfigures", "figures\n{close}", "{close}\nfigures\n{open}",
                                    "{open}\na\n{close}\n{open}\nb\n{close}"])
def test_markers_that_are_not_one_ordered_pair_are_refused_naming_the_module(broken):
    text = "# Benchmarks\n\n" + broken.format(open=run.begin("bench_a"), close=run.end("bench_a"))
    with pytest.raises(ValueError, match="markers of bench_a"):
        run.splice(text, "bench_a", "### A")


def test_the_stamp_names_the_machine_date_time_and_load_under_the_title():
    out = run.stamped("### Title (5 pairs)\n\n| a |\n|---|\n| 1 |\n", "CPU X, 2 cores", "2026-01-02", 41.6,
                      (0.84, 2.05))
    assert out.splitlines()[:4] == ["### Title (5 pairs)", "", "Measured on CPU X, 2 cores, 2026-01-02, in 42 s; load "
                                    "average 0.8 before and 2.0 after.", ""]
    assert out.endswith("| a |\n|---|\n| 1 |")


@pytest.fixture
def fake_modules(monkeypatch, tmp_path):
    """Two benchmark modules whose figures are the number of times they were measured, and a BENCHMARKS.md with
    notes around their blocks."""
    counts = {}
    for name in ("bench_one", "bench_two"):
        module = types.ModuleType(f"benchmarks.{name}")
        module.measure = lambda name=name: counts.__setitem__(name, counts.get(name, 0) + 1) or counts[name]
        module.markdown = lambda r, name=name: f"### {name}\n\nmeasured {r} times\n"
        monkeypatch.setitem(sys.modules, f"benchmarks.{name}", module)
    monkeypatch.setattr(run, "MODULES", ("bench_one", "bench_two"))
    target = tmp_path / "BENCHMARKS.md"
    target.write_text(NOTES.format(a=_block("bench_one", "### bench_one\n\nold"), b="Nothing of two yet."))
    monkeypatch.setattr(run, "TARGET", target)
    return target


def test_a_run_of_one_module_replaces_its_block_alone(fake_modules, capsys):
    before = fake_modules.read_text()
    assert run.main(["bench_one"]) == 0
    after = fake_modules.read_text()
    assert "measured 1 times" in after and "bench_two" not in after
    assert _outside(after, ["bench_one"]) == _outside(before, ["bench_one"])
    assert run.main([]) == 0  # every module: one's block again, two's appended
    again = fake_modules.read_text()
    assert "measured 2 times" in again and "measured 1 times" in again  # one's second, two's first
    assert again.index(run.begin("bench_one")) < again.index("Nothing of two yet.") < again.index(
        run.begin("bench_two"))
    assert _outside(again, ["bench_one", "bench_two"]).rstrip() == _outside(before, ["bench_one"]).rstrip()


def test_an_unknown_module_is_refused_in_one_line_and_nothing_written(fake_modules, capsys):
    before = fake_modules.read_bytes()
    assert run.main(["bench_one", "bench_typo"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'bench_typo'" in err and "bench_one, bench_two" in err
    assert fake_modules.read_bytes() == before


def test_a_failed_write_leaves_the_file_as_it_was_and_no_file_beside_it(fake_modules, monkeypatch):
    before = fake_modules.read_bytes()

    def refuse(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(run.os, "replace", refuse)
    with pytest.raises(OSError, match="disk full"):
        run.main(["bench_one"])
    assert fake_modules.read_bytes() == before
    assert [p.name for p in fake_modules.parent.iterdir()] == ["BENCHMARKS.md"]


def test_a_child_of_a_large_parent_reports_its_own_peak_memory():
    ballast = np.ones(400 * 2**20 // 8)  # 400 MiB, touched
    code = f"import resource; print({CHILD_PEAK_BYTES}, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024)"
    own, inherited = map(int, subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                                             check=True).stdout.split())
    assert own < 100 * 2**20 < 400 * 2**20 <= resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
    assert inherited >= 400 * 2**20  # why: getrusage carries the parent's high-water mark across exec
    del ballast


def test_the_outputs_digest_answers_help_and_writes_no_file_named_after_it(tmp_path, capsys, monkeypatch):
    """`--help` is an option, not the digest's file name (it ran every scenario and wrote a file '--help')."""
    from benchmarks import outputs_digest

    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as done:
        outputs_digest.main(["--help"])
    assert done.value.code == 0
    assert "--compare BEFORE AFTER" in capsys.readouterr().out
    assert not list(tmp_path.iterdir())

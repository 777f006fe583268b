"""The run budget (simbench.core.budget): the estimate against what runs really allocate, and the refusal of runs the
machine cannot afford, before anything big is allocated: exit 2, one line naming the field, nothing written, a
small process; a large but possible run says what it will cost."""

import dataclasses
import os
import subprocess
import sys
import textwrap
import tracemalloc

import numpy as np
import pytest
import yaml

from simbench.cli import main
from simbench.commands import pipeline
from simbench.commands.sweep import load_sweep, run_sweep
from simbench.core import budget, windowed
from simbench.core.errors import ScenarioError
from simbench.core.plant import compiled_scene
from simbench.planners import rsmg_lazy
from simbench.scenario import load_scenario, parse_scenario
from tests.conftest import SHIPPED, scenario_file

# Runs long enough that the per-sample terms dominate, short enough for the test suite (about 1 s each).
CALIBRATION = [("spherical_arm", "case1", 40.0), ("rsmg", "three_turns", 30.0),
               ("agile_eye", "through_singularity", 8.0)]


def scaled(path, **fields) -> dict:
    """A scenario file's document with dotted fields (timing.duration=...) set."""
    doc = yaml.safe_load(path.read_text())
    for dotted, value in fields.items():
        section, name = dotted.split(".")
        doc.setdefault(section, {})[name] = value
    return doc


def write(tmp_path, doc: dict, name: str = "scenario"):
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def on_heap(monkeypatch) -> None:
    """The RSMG search's cached arrays kept on the heap, as copies, rather than on pages of their own
    (rsmg_lazy.on_own_pages), which tracemalloc does not see: the bytes a run holds are then all traced."""
    monkeypatch.setattr(rsmg_lazy, "on_own_pages", np.copy)


@pytest.mark.parametrize("every", [1, 10])
@pytest.mark.parametrize(("robot", "name", "duration"), CALIBRATION)
def test_estimate_is_within_a_factor_of_what_a_run_allocates(monkeypatch, robot, name, duration, every):
    """The estimated peak against tracemalloc's peak of evaluate() (both above the start; the RSMG search's cache
    traced too: `on_heap`), within 1/1.5 to 2, recorded whole and with a recording stride; the samples exactly as
    the plan has them (all analysed; the evaluation keeps the recorded rows)."""
    path = scenario_file(robot, name)
    doc = scaled(path, **{"timing.duration": duration, "sim.record_every": every})
    sc = parse_scenario(doc, str(path), default_name=name)
    model = compiled_scene(str(sc.robot_def.scene))  # compiled once per process: not the run's own allocation
    shipped = load_scenario(path)  # nor the libraries a planner imports when it first plans (scipy's, say)
    shipped.planner_def.plan(shipped, shipped.robot_def, float(model.opt.timestep))
    est = budget.estimate(budget.Ask.of(sc))
    on_heap(monkeypatch)
    tracemalloc.start()
    try:
        start = tracemalloc.get_traced_memory()[0]
        ev = pipeline.evaluate(sc)
        peak = tracemalloc.get_traced_memory()[1] - start
    finally:
        tracemalloc.stop()
    assert est.samples == ev.analysis.samples  # every sample of the plan analysed
    assert len(ev.trajectory.t) == len(ev.recording.t) == len(ev.analysis.series["tool_error"])  # the kept rows
    assert peak / 1.5 <= est.memory <= 2.0 * peak, (est.memory, peak)


@pytest.mark.parametrize(("robot", "name", "duration", "every"), [("spherical_arm", "case1", 150.0, 10),
                                                            ("rsmg", "three_turns", 100.0, 20)])
def test_a_run_analysed_as_it_is_simulated_is_estimated_by_its_window(monkeypatch, robot, name, duration, every):
    """A strided run of several windows, analysed as it is simulated: the estimate against tracemalloc's peak of
    evaluate() (every step's readings held a window at a time among them: simbench.core.buffers; the RSMG search's
    cache traced too: `on_heap`), within 1/1.5 to 2; and below what the model of a run held whole estimates for
    it."""
    path = scenario_file(robot, name)
    sc = parse_scenario(scaled(path, **{"timing.duration": duration, "sim.record_every": every}), str(path),
                        default_name=name)
    model = compiled_scene(str(sc.robot_def.scene))
    shipped = load_scenario(path)
    shipped.planner_def.plan(shipped, shipped.robot_def, float(model.opt.timestep))
    ask = budget.Ask.of(sc)
    est = budget.estimate(ask)
    assert ask.streams and est.samples > windowed.WINDOW
    on_heap(monkeypatch)
    tracemalloc.start()
    try:
        start = tracemalloc.get_traced_memory()[0]
        pipeline.evaluate(sc)
        peak = tracemalloc.get_traced_memory()[1] - start
    finally:
        tracemalloc.stop()
    assert peak / 1.5 <= est.memory <= 2.0 * peak, (est.memory, peak)
    assert est.memory < budget.estimate(dataclasses.replace(ask, streams=False)).memory


def test_the_machine_limits_are_what_it_has():
    """Half the memory available now (which moves a little between two looks), at most the cap; the disk where
    the outputs would go, from the nearest folder that exists."""
    limits = budget.Limits.of_machine("renders/nothing/here")
    assert 0 < limits.memory <= budget.MEMORY_CAP
    assert limits.memory <= 1.1 * budget.MEMORY_FRACTION * budget.available_memory()
    assert limits.disk is not None and limits.disk > 0 and limits.seconds == budget.TIME_LIMIT


def _mem_available() -> int:
    """The kernel's MemAvailable, read from /proc/meminfo."""
    with open("/proc/meminfo") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith("MemAvailable:"))


@pytest.mark.skipif(not os.path.exists("/proc/meminfo"), reason="no /proc/meminfo to compare with")
def test_the_memory_available_is_the_kernels_or_the_cgroups_left(tmp_path, monkeypatch):
    """Without a cgroup limit, the kernel's MemAvailable (/proc/meminfo; it moves a little between two looks);
    under a cgroup limit lower than that (v2 or v1 files), the limit less the usage; a limit of "max" is none."""
    limit, usage, none = tmp_path / "memory.max", tmp_path / "memory.current", tmp_path / "none"
    monkeypatch.setattr(budget, "_CGROUP_FILES", ((str(none), str(none)), (str(limit), str(usage))))
    assert budget.available_memory() == pytest.approx(_mem_available(), rel=0.05)
    limit.write_text("max\n")
    usage.write_text("123\n")
    assert budget.available_memory() == pytest.approx(_mem_available(), rel=0.05)
    limit.write_text(f"{2**30}\n")
    usage.write_text(f"{2**28}\n")
    assert budget.available_memory() == 2**30 - 2**28
    usage.write_text(f"{2**31}\n")
    assert budget.available_memory() == 0


# Each way to ask too much: the fields changed, and the field the refusal must name. Durations and timesteps are
# scaled within the schema's own bounds; the limit is put between the shipped scenario's estimate and the scaled
# one, so that each refusal is that of the combination, not of a field out of its range. (sim.settle, at most
# 10 s, matters only where the run is short: test_a_long_settle_is_named.)
EXCESSES = {
    "duration": ({"timing.duration": lambda d: min(d * 20_000, 80_000.0)}, "timing.duration", False),
    "timestep": ({"sim.timestep": lambda dt: max((dt or 5e-4) / 50, 1e-5)}, "sim.timestep", False),
    "hold": ({"timing.hold": lambda h: 60.0}, "timing.hold", False),
    "fps": ({"render.fps": lambda f: 120}, "render.fps", True),
    "size": ({"render.width": lambda w: 1920, "render.height": lambda h: 1080}, "render.width", True),
}


def _excess(path, kind):
    changes, field, video = EXCESSES[kind]
    raw = yaml.safe_load(path.read_text())
    fields = {}
    for dotted, scale in changes.items():
        section, name = dotted.split(".")
        fields[dotted] = scale(raw.get(section, {}).get(name))  # the value as shipped, None where defaulted
    return scaled(path, **fields), field, video


@pytest.mark.parametrize("kind", list(EXCESSES))
@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_a_run_asking_too_much_is_refused_naming_the_field(path, kind, tmp_path, capsys, monkeypatch):
    """Every shipped scenario, with one field scaled: `simbench run` exits 2 with one line naming the field, the
    estimate, the limit and the way out, and writes nothing; the scenario as shipped passes the same limits."""
    doc, field, video = _excess(path, kind)
    shipped = budget.estimate(budget.Ask.of(load_scenario(path), video=video, outputs=True))
    asked = budget.estimate(budget.Ask.of(parse_scenario(doc, str(path)), video=video, outputs=True))
    if video:
        assert asked.seconds > 2 * shipped.seconds
        limits = budget.Limits(memory=budget.MEMORY_CAP, seconds=(asked.seconds * shipped.seconds) ** 0.5)
        resource = "would take about"
    else:
        assert asked.memory > 1.3 * shipped.memory, (asked.memory, shipped.memory)
        limits = budget.Limits(memory=int((asked.memory * shipped.memory) ** 0.5), memory_basis="the test's")
        resource = "of memory"
    monkeypatch.setattr(budget, "machine_limits", lambda out=None: limits)
    budget.check(load_scenario(path), video=video, outputs=True)  # the shipped scenario fits
    scenario = write(tmp_path, doc, path.stem)
    out = tmp_path / "out"
    code = main(["run", str(scenario), "--out", str(out), "--quiet"] + ([] if video else ["--no-video"]))
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(lines) == 1, lines
    assert lines[0].startswith(f"error: {scenario}: {field}: the run ")
    assert resource in lines[0] and "more than the" in lines[0]
    assert any(verb in lines[0] for verb in ("shorten", "raise", "lower", "shrink")), lines[0]
    assert not out.exists() and sorted(p.name for p in tmp_path.iterdir()) == [scenario.name]


def test_a_long_settle_is_named(tmp_path, capsys, monkeypatch):
    """Settling 10 s before a 4.5 s run triples its steps: past a limit in between, sim.settle is named."""
    path = scenario_file("spherical_arm", "case1")
    doc = scaled(path, **{"sim.settle": 10.0})
    shipped = budget.estimate(budget.Ask.of(load_scenario(path))).memory
    asked = budget.estimate(budget.Ask.of(parse_scenario(doc, str(path)))).memory
    assert asked > 2 * shipped
    limits = budget.Limits(memory=int((asked * shipped) ** 0.5))
    monkeypatch.setattr(budget, "machine_limits", lambda out=None: limits)
    scenario = write(tmp_path, doc)
    assert main(["run", str(scenario), "--out", str(tmp_path / "out"), "--no-video"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {scenario}: sim.settle: the run would need"), lines
    assert "shorten sim.settle to at most" in lines[0] and not (tmp_path / "out").exists()


def test_validate_and_evaluate_refuse_it_too(tmp_path, capsys):
    """The budget holds for `validate` (it plans) and for the Python API, whatever the machine (beyond the cap)."""
    path = scenario_file("spherical_arm", "case1")
    doc = scaled(path, **{"timing.duration": 80_000.0})
    scenario = write(tmp_path, doc)
    assert main(["validate", str(scenario)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {scenario}: timing.duration: ")
    assert "shorten timing.duration to at most" in lines[0]
    with pytest.raises(ScenarioError, match="timing.duration: the run would need about"):
        pipeline.evaluate(load_scenario(scenario))


def test_a_refused_run_stays_small(tmp_path):
    """The refusal comes before anything big is allocated: the whole `python -m simbench run` of a scenario
    asking hundreds of GB peaks under 200 MB resident."""
    path = scenario_file("spherical_arm", "case1")
    scenario = write(tmp_path, scaled(path, **{"timing.duration": 3600.0, "sim.timestep": 1e-4}))
    out = tmp_path / "out"
    probe = textwrap.dedent(f"""
        import resource, subprocess, sys
        done = subprocess.run([sys.executable, "-m", "simbench", "run", {str(scenario)!r}, "--out", {str(out)!r}],
                              capture_output=True, text=True)
        print(done.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
        sys.stderr.write(done.stderr)
    """)
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120)
    code, peak_kib = map(int, done.stdout.split())
    lines = done.stderr.strip().splitlines()
    assert code == 2 and len(lines) == 1, done.stderr
    assert lines[0].split(": ")[2] in ("sim.timestep", "timing.duration"), lines[0]
    assert peak_kib < 200 * 1024, peak_kib
    assert not out.exists()


def test_a_large_run_says_what_it_will_cost(tmp_path, capsys, monkeypatch):
    """Above the note's thresholds (lowered here: a large run takes minutes) the run goes on and says its cost in
    one line on stderr, before running; --quiet says nothing."""
    monkeypatch.setattr(budget, "NOTE_MEMORY", 1e6)
    path = scenario_file("spherical_arm", "case1")
    assert main(["run", str(path), "--out", str(tmp_path / "a"), "--no-video"]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("note: a large run: about ") and "4,501 samples" in err[0], err
    assert main(["run", str(path), "--out", str(tmp_path / "b"), "--no-video", "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    est = budget.estimate(budget.Ask.of(load_scenario(path)))
    assert est.memory < budget.NOTE_MEMORY * 1000 and est.seconds < budget.NOTE_SECONDS  # shipped: no note
    monkeypatch.setattr(budget, "NOTE_MEMORY", 1e9)
    assert est.note() is None


def test_a_long_video_is_estimated_and_refused_past_the_time_limit():
    """3000 s of 1080p at 120 fps: frames, bytes and hours estimated; past the time limit it names the video's
    fields or the duration and offers --no-video."""
    path = scenario_file("spherical_arm", "case1")
    doc = scaled(path, **{"timing.duration": 3000.0, "render.fps": 120, "render.width": 1920,
                          "render.height": 1080})
    sc = parse_scenario(doc, str(path))
    est = budget.estimate(budget.Ask.of(sc, video=True, outputs=True))
    assert est.frames == 3000.5 * 120 + 1 and est.seconds > 3600 and est.video_bytes > 1e8
    assert "video frames" in est.note()
    limits = budget.Limits(memory=budget.MEMORY_CAP, seconds=3600.0)
    with pytest.raises(ScenarioError, match="would take about .* more than the 1 h simbench allows a run; .*"
                                            "or run with --no-video") as err:
        budget.check(sc, video=True, outputs=True, limits=limits)
    assert err.value.field in ("timing.duration", "render.fps", "render.width")
    budget.check(sc, video=False, limits=budget.Limits(memory=budget.MEMORY_CAP, seconds=3600.0))  # physics only


def test_a_refused_sweep_variant_is_a_bad_input_row(tmp_path, monkeypatch):
    """A sweep's variant past the budget is its row's bad_input, as a schema refusal is; the others run."""
    monkeypatch.setattr(budget, "machine_limits", lambda out=None: budget.Limits(memory=4 * 2**30))
    spec = {"base": "spherical_arm/case1", "outputs": "none", "grid": {"timing.duration": [2, 80_000]}}
    sweep_file = tmp_path / "sweep.yaml"
    sweep_file.write_text(yaml.safe_dump(spec))
    result = run_sweep(load_sweep(sweep_file), tmp_path / "out", workers=1)
    rows = (tmp_path / "out" / "results.csv").read_text().splitlines()
    assert result.summary["status"]["ok"] + result.summary["status"]["limits"] == 1
    assert result.summary["status"]["bad_input"] == 1
    assert any("timing.duration: the run would need about" in row for row in rows[1:])

"""The benchmark's definition is versioned (issue 47): a suite names the version its tasks are drawn by (sb-1),
summary.json carries the version, the seed and each arm's model hash, a version simbench does not have is refused in
one line (exit 2), and a bench folder of one version does not resume as another. Truths: the model file's bytes
(hashlib), the folder's manifest as JSON, and the CLI's exit status and stderr."""

import csv
import hashlib
import json
import shutil
import xml.etree.ElementTree as ET
from dataclasses import replace
from importlib.metadata import version
from pathlib import Path

import dm_control
import pytest

from simbench.cli import main
from simbench.commands.bench import load_suite
from simbench.commands.bench import tasks as bench_tasks
from simbench.commands.bench.robots import SHIPPED, BenchRobot
from simbench.commands.bench.runner import plan_bench
from simbench.core.resources import models_dir

MODEL = models_dir() / "spherical_arm" / "spherical_arm.xml"  # one file: it includes none


def _suite_file(folder, version=None):
    """A suite file of one spherical-arm task by dls_adaptive at seed 11, stating `version` where given."""
    path = folder / f"tiny-{version}.yaml"
    path.write_text("name: tiny\n" + (f"version: {version}\n" if version else "")
                    + "tasks: 1\nseed: 11\nmethods: [dls_adaptive]\nrobots: [spherical_arm]\n")
    return path


def _hash(*files) -> str:
    """The first 16 hex digits of SHA-256 over the SHA-256 digests of the files' bytes, in order."""
    return hashlib.sha256(b"".join(hashlib.sha256(f.read_bytes()).digest() for f in files)).hexdigest()[:16]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The tiny bench run through the CLI, its suite file stating sb-1; its output folder."""
    folder = tmp_path_factory.mktemp("version")
    out = folder / "out"
    assert main(["bench", str(_suite_file(folder, "sb-1")), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    return out


def test_summary_carries_the_version_the_seed_and_the_model_hash_of_its_files_bytes(tiny):
    """summary.json: sb-1, seed 11, the simbench that ran it (its installed metadata's), and the spherical arm's
    hash recomputed from its file's bytes; the folder's manifest holds the same version and hash."""
    out = tiny
    summary = json.loads((out / "summary.json").read_text())
    assert summary["version"] == "sb-1" and summary["seed"] == 11 and summary["runs"] == 1
    assert summary["simbench"] == version("simbench")
    assert summary["models"] == {"spherical_arm": _hash(MODEL)}
    manifest = json.loads((out / "sweep.json").read_text())["spec"]
    assert manifest["version"] == "sb-1" and manifest["models"] == summary["models"]


def test_every_table_says_the_version_the_seed_and_the_model_hash_of_each_row(tiny):
    """runs.csv, leaderboard.csv and leaderboard_by_kind.csv (read back with the csv module) end each row with the
    benchmark version, the seed and the row's robot's model hash recomputed from its file's bytes (paired.csv too,
    test_bench_paired's benches: one method here, no pair)."""
    assert not (tiny / "paired.csv").read_text().strip()
    for name in ("runs.csv", "leaderboard.csv", "leaderboard_by_kind.csv"):
        with open(tiny / name, newline="") as handle:
            header, *rows = list(csv.reader(handle))
        assert header[-3:] == ["version", "seed", "model_hash"] and rows, name
        for row in rows:
            assert row[header.index("robot")] == "spherical_arm"
            assert row[-3:] == ["sb-1", "11", _hash(MODEL)], name


def test_a_shipped_suite_and_a_file_without_a_version_are_the_newest(tmp_path):
    assert bench_tasks.GENERATOR == "sb-1" and list(bench_tasks.VERSIONS) == ["sb-1"]
    assert load_suite("spherical_arm").version == load_suite(_suite_file(tmp_path)).version == "sb-1"


def test_an_edited_model_has_another_hash(tmp_path):
    """A byte changed in a copy of the model changes its hash; the copy as it was has the original's."""
    copy = tmp_path / "arm.xml"
    shutil.copy(MODEL, copy)
    robot = BenchRobot("copy", {"model": str(copy)})
    assert robot.model_hash() == SHIPPED["spherical_arm"]().model_hash()
    copy.write_text(copy.read_text() + "\n<!-- edited -->\n")
    assert robot.model_hash() == _hash(copy) != _hash(MODEL)


def test_an_mjcf_arms_hash_covers_the_file_it_includes_and_the_meshes_it_names():
    """The Jaco (dm_control's MJCF): its file, then common.xml (which it includes), then each <mesh file> in
    document order by its name, a NUL byte and the SHA-256 of the file under the compiler's meshdir."""
    jaco = Path(dm_control.__file__).parent / "third_party" / "kinova" / "jaco_arm.xml"
    root = ET.parse(jaco).getroot()
    meshes = jaco.parent / root.find("compiler").get("meshdir")
    digest = hashlib.sha256(b"".join(hashlib.sha256(f.read_bytes()).digest()
                                     for f in (jaco, jaco.parent / "common.xml")))
    for mesh in root.iter("mesh"):
        digest.update(mesh.get("file").encode() + b"\0" + hashlib.sha256((meshes / mesh.get("file")).read_bytes())
                      .digest())
    assert SHIPPED["jaco"]().model_hash() == digest.hexdigest()[:16]


def test_a_bench_of_an_edited_model_is_another_bench(tmp_path):
    """The spherical arm's suite of one task on a copy of its model: the bench's fingerprint (what a folder resumes
    by, simbench.commands.sweep.store) changes when a byte of the copy does, though its tasks do not (a comment)."""
    copy = tmp_path / "arm.xml"
    shutil.copy(MODEL, copy)
    shipped = load_suite("spherical_arm").with_options(tasks=1, methods=["dls_adaptive"])

    def bench():
        robot = replace(shipped.robots[0], mapping={**shipped.robots[0].mapping, "model": str(copy)}, cache={})
        return plan_bench(replace(shipped, robots=(robot,)))

    before = bench()
    copy.write_text(copy.read_text() + "\n<!-- edited -->\n")
    after = bench()
    assert [v.document["task"] for v in after.variants] == [v.document["task"] for v in before.variants]
    assert after.spec.models == {"spherical_arm": _hash(copy)} != before.spec.models
    assert after.fingerprint() != before.fingerprint()


@pytest.mark.parametrize("value, shown", [("sb-0", "'sb-0'"), ("sb-2", "'sb-2'"), ("1", None)])
def test_a_version_simbench_does_not_have_is_refused_in_one_line(tmp_path, capsys, value, shown):
    path = _suite_file(tmp_path, value)
    assert main(["bench", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"error: {path}: version: "), lines
    if shown:
        assert f"unknown benchmark version {shown} (this simbench has: sb-1)" in lines[0]
    assert not (tmp_path / "out").exists()


def test_a_folder_of_one_version_does_not_resume_as_another(tiny, monkeypatch, tmp_path, capsys):
    """With a second version beside sb-1 (drawing the same tasks), the tiny bench's folder is refused as the other
    (exit 2, one line), its files as they were, and resumes from a file differing in nothing else, stating sb-1
    (nothing left to run)."""
    out = tiny
    monkeypatch.setitem(bench_tasks.VERSIONS, "sb-test", bench_tasks.VERSIONS["sb-1"])
    before = (out / "summary.json").read_text()
    assert main(["bench", str(_suite_file(tmp_path, "sb-test")), "--out", str(out), "--quiet"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "the output folder holds other results" in lines[0], lines
    assert (out / "summary.json").read_text() == before
    assert main(["bench", str(_suite_file(tmp_path, "sb-1")), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    assert json.loads((out / "summary.json").read_text())["resumed"] == 1

"""A run's timeseries as CSV (simbench.outputs.export; `simbench export RUN_FOLDER`, `simbench run --timeseries csv`).

Every per-sample array of timeseries.npz is read back from the CSV, by the csv module and float(), equal to the
npz's to the last bit; the header's units are checked against the model file's own joint types (a URDF's
`type="revolute"`) and against the spherical arm's paper (q2 and q4 slide); names from a model come back exactly
as written; a bad run folder or a timeseries.csv of the user's is one line, exit 2, with nothing written.
"""

import csv
import json
import xml.etree.ElementTree as ET
from importlib.metadata import distribution
from pathlib import Path

import numpy as np
import pytest

from simbench.cli import main
from simbench.core import destination
from simbench.outputs.csv_cells import FORMULA_STARTS
from tests.commands.test_reliability import stiff_puma

PACKAGE = Path(str(distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data")))
UR5 = PACKAGE / "robots" / "ur_description" / "urdf" / "ur5_robot.urdf"
UR5_START = [0.834, 0.0016, -1.8601, -0.0508, -1.263, -1.6155]  # mid-reach, clear of contacts (test_derived_plant)


def ur5_line(folder: Path, name: str = "ur5", task: str = "") -> Path:
    """A short UR5 line scenario (SI): 5 cm along x in 0.5 s from the URDF untouched, orientation held; `task`
    more task fields, one a line."""
    more = "".join(f"  {line}\n" for line in task.splitlines())
    path = folder / f"{name}.yaml"
    path.write_text(f"robot: {json.dumps({'model': str(UR5), 'tool': {'body': 'tool0'}})}\nplanner: cartesian_path\n"
                    f"task:\n  start: {UR5_START}\n  path:\n    - line: {{by: [0.05, 0.0, 0.0]}}\n  orientation: hold\n"
                    f"{more}timing: {{duration: 0.5, hold: 0.1}}\n")
    return path


def read_csv(path: Path) -> tuple[list[str], dict[str, np.ndarray]]:
    """The header and every column as floats (float() of each cell: Python's own decimal reading)."""
    with open(path, newline="", encoding="utf-8") as f:
        header, *rows = list(csv.reader(f))
    return header, {name: np.array([float(row[i]) for row in rows]) for i, name in enumerate(header)}


def urdf_units(path: Path, joints) -> list[str]:
    """Each joint's position unit by the URDF's own joint type."""
    types = {j.get("name"): j.get("type") for j in ET.parse(path).getroot().findall("joint")}
    return [{"revolute": "rad", "continuous": "rad", "prismatic": "m"}[types[j]] for j in joints]


def expected_columns(name: str, shape: tuple, joints: list[str]) -> list[str]:
    """The column names (without units) of a per-sample array, written out as the docs name them."""
    if shape == ():
        return [name]
    if shape == (len(joints),) and name in ("q_ref", "qd_ref", "q", "qd", "joint_error", "actuator_force"):
        return [f"{name}_{j}" for j in joints]
    if name in ("tool", "tool_ref"):
        return [f"{name}_{a}" for a in "xyz"]
    if name == "tool_orientation_ref":
        return [f"{name}_{a}" for a in "wxyz"]
    return [f"{name}_{'_'.join(map(str, i))}" for i in np.ndindex(*shape)]


def assert_round_trips(folder: Path) -> dict[str, str]:
    """Every per-sample array of the folder's timeseries.npz equals its CSV columns to the bit, and the CSV has no
    other column; each column's unit by name."""
    header, columns = read_csv(folder / "timeseries.csv")
    names = [h.rsplit(" [", 1)[0] for h in header]
    units = dict(h[:-1].rsplit(" [", 1) for h in header)
    z = np.load(folder / "timeseries.npz")
    joints = [str(j) for j in z["joints"]]
    n = z["t"].size
    expected = []
    for name in z.files:
        value = z[name]
        if name == "joints":
            continue
        assert value.shape[0] == n, name  # every other array simbench writes is one row a sample
        labels = expected_columns(name, value.shape[1:], joints)
        expected += labels
        flat = value.reshape(n, -1).astype(float)
        for k, label in enumerate(labels):
            got = columns[header[names.index(label)]]
            assert got.tobytes() == flat[:, k].tobytes(), label
    assert names == expected
    return units


@pytest.fixture(scope="module")
def ur5_run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("export")
    path, out = ur5_line(folder), folder / "out"
    assert main(["run", str(path), "--out", str(out), "--no-video", "--quiet", "--timeseries", "csv"]) == 0
    return path, out


def test_run_timeseries_csv_round_trips_every_array_with_units_in_the_header(ur5_run):
    _, out = ur5_run
    units = assert_round_trips(out)
    joints = [str(j) for j in np.load(out / "timeseries.npz")["joints"]]
    position = urdf_units(UR5, joints)
    assert position == ["rad"] * 6
    for joint, unit in zip(joints, position):
        assert units[f"q_{joint}"] == units[f"q_ref_{joint}"] == units[f"joint_error_{joint}"] == unit
        assert units[f"qd_{joint}"] == units[f"qd_ref_{joint}"] == f"{unit}/s"
        assert units[f"actuator_force_{joint}"] == "N m"
    assert units["t"] == "s" and units["tool_x"] == units["tool_ref_z"] == units["tool_error"] == "m"
    assert units["path_deviation"] == "m" and units["tool_orientation_error"] == "rad"
    assert units["inverse_condition"] == units["sigma_min_unit"] == "1" and units["sigma_min"] == "SI"
    with open(out / "timeseries.csv", encoding="utf-8") as f:
        assert f.readline().startswith("t [s],s [1],q_ref_shoulder_pan_joint [rad],")


def test_the_export_command_writes_the_same_file_and_the_folder_stays_simbenchs(ur5_run, capsys):
    """`simbench export` finds the joints' kinds in the scenario file the report names, as the run had them; the
    file is listed in the folder's marker, so that `--force` still replaces the folder."""
    _, out = ur5_run
    written = (out / "timeseries.csv").read_bytes()
    (out / "timeseries.csv").unlink()
    assert main(["export", str(out)]) == 0
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith(f"{out / 'timeseries.csv'}: 301 rows, ") and len(printed) == 1
    assert (out / "timeseries.csv").read_bytes() == written
    assert main(["export", str(out), "--format", "csv"]) == 0  # over its own file
    assert (out / "timeseries.csv").read_bytes() == written
    assert destination.foreign(out) == []
    destination.check_replace(out, removes=True)  # what run --force checks: no refusal


def test_a_failed_runs_timeseries_is_exported_too(tmp_path, capsys):
    path, out = stiff_puma(tmp_path), tmp_path / "out"
    assert main(["run", str(path), "--out", str(out), "--quiet", "--timeseries", "csv"]) == 1
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
    units = assert_round_trips(out)
    assert units["q_q3"] == "rad" and units["qd_q3"] == "rad/s"


def fabricated(folder: Path, robot: str, joints: list[str], derived: bool = False, **arrays) -> Path:
    """A run folder as simbench writes one, its arrays given (t, 7 samples, added)."""
    folder.mkdir()
    np.savez(folder / "timeseries.npz", t=np.arange(7) * 0.1, joints=np.array(joints), **arrays)
    report = {"robot": robot, "scenario": {"name": "x", "file": str(folder / "gone.yaml"), "description": ""}}
    if derived:
        report["derived_arm"] = {}
    (folder / "report.json").write_text(json.dumps(report))
    destination.mark(folder)
    return folder


def test_a_shipped_robots_sliding_joints_are_in_metres_and_other_arrays_by_index(tmp_path, capsys):
    """The spherical arm (paper 000): q2 lifts and q4 reaches, in metres; a boolean series as 0 and 1, an array of
    two axes by index pairs, a series simbench does not know marked `?`, one not a value a sample left out."""
    rng = np.random.default_rng(0)
    q = rng.normal(size=(7, 4))
    q[0, 0] = np.nextafter(1.0, 2.0)  # the last bit counts
    folder = fabricated(tmp_path / "run", "spherical_arm", ["q1", "q2", "q3", "q4"], q=q, qd=rng.normal(size=(7, 4)),
                        engaged=rng.normal(size=(7, 4)) > 0, frames=rng.normal(size=(7, 2, 3)),
                        my_series=rng.normal(size=7), waypoints=rng.normal(size=(3, 4)))
    assert main(["export", str(folder)]) == 0
    assert capsys.readouterr().out.splitlines()[1:] == ["  note: waypoints left out: not one number a sample"]
    header, columns = read_csv(folder / "timeseries.csv")
    assert header == ["t [s]", "q_q1 [rad]", "q_q2 [m]", "q_q3 [rad]", "q_q4 [m]", "qd_q1 [rad/s]", "qd_q2 [m/s]",
                      "qd_q3 [rad/s]", "qd_q4 [m/s]", *(f"engaged_{i} [1]" for i in range(4)),
                      *(f"frames_{i}_{j} [?]" for i in range(2) for j in range(3)), "my_series [?]"]
    assert columns["q_q1 [rad]"].tobytes() == q[:, 0].tobytes()
    with open(folder / "timeseries.csv", encoding="utf-8") as f:
        assert {cell for line in f.readlines()[1:] for cell in line.strip().split(",")[9:13]} == {"0", "1"}
    assert columns["frames_1_0 [?]"].tobytes() == np.load(folder / "timeseries.npz")["frames"][:, 1, 0].tobytes()


def test_names_from_a_model_come_back_as_written_and_unknown_kinds_say_so(tmp_path):
    """A derived arm whose scenario file is gone: its joints' kinds cannot be known (rad or m); joint names with
    a comma, a quote, a line break or a formula's start are read back exactly, no cell a formula."""
    joints = ['a,"b"', "line\nbreak", "=HYPERLINK(\"http://x\")", "+1"]
    folder = fabricated(tmp_path / "run", "arm", joints, derived=True, q=np.ones((7, 4)))
    assert main(["export", str(folder)]) == 0
    header, _ = read_csv(folder / "timeseries.csv")
    assert header == ["t [s]", *(f"q_{j} [rad or m]" for j in joints)]
    assert not any(h.startswith(FORMULA_STARTS) for h in header)


@pytest.mark.parametrize("case", ["missing", "file", "empty", "garbage npz", "no t", "garbage report"])
def test_a_bad_run_folder_is_one_line_exit_2_and_nothing_is_written(tmp_path, capsys, case):
    folder = tmp_path / "run"
    named = folder
    if case == "file":
        folder.write_text("not a folder")
    elif case == "empty":
        folder.mkdir()
    elif case in ("garbage npz", "garbage report"):
        fabricated(folder, "puma600", ["q1"], q=np.zeros((7, 1)))
        named = folder / ("timeseries.npz" if case == "garbage npz" else "report.json")
        named.write_bytes(b"PK\x03\x04 not what it says")
    elif case == "no t":
        folder.mkdir()
        np.savez(folder / "timeseries.npz", q=np.zeros((3, 1)), joints=np.array(["q1"]))
        (folder / "report.json").write_text("{}")
        named = folder / "timeseries.npz"
    before = sorted(tmp_path.rglob("*"))
    assert main(["export", str(folder)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {named}: "), err
    assert sorted(tmp_path.rglob("*")) == before


@pytest.mark.parametrize("mine", ["file", "symlink", "folder"])
def test_a_timeseries_csv_simbench_did_not_write_is_never_replaced(tmp_path, capsys, mine):
    folder = fabricated(tmp_path / "run", "puma600", ["q1"], q=np.zeros((7, 1)))
    target = folder / "timeseries.csv"
    notes = tmp_path / "notes.csv"
    notes.write_text("my notes\n")
    if mine == "file":
        target.write_text("my notes\n")
    elif mine == "symlink":
        target.symlink_to(notes)
    else:
        target.mkdir()
    assert main(["export", str(folder)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {target}: ") and "did not write" in err[0]
    assert notes.read_text() == "my notes\n"
    assert target.is_symlink() if mine == "symlink" else (target.read_text() == "my notes\n" if mine == "file"
                                                          else target.is_dir())

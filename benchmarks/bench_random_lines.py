"""Random straight lines on arms nobody here modelled (issues 35 and 44): dm-control's Kinova Jaco (MJCF) and the UR5,
xArm7 and Z1 of example-robot-data (URDF), read from their installs untouched, with the `cartesian_path` planner.

LINES lines per arm (seed SEED): each one's start configuration drawn uniformly within the joint ranges, 10 % of
each range's width away from its ends (a continuous joint within -180..180 deg), its end point at a uniform random
direction and a length of 50-300 mm from the start's tool point; a draw whose start or end point lies under
FLOOR_CLEARANCE above the floor is drawn again. Duration: the length at SPEED (at least 1 s), hold 0.3 s. Each
line is run by simbench.run without video into a temporary folder, and ends `ok`, `limits` (its violation kinds
tallied, and each run counted once under each cause its kinds fall under, bench_arms.CAUSES; and whether an
actuator saturates from the first sample, the set-up's doing), refused
(ScenarioError: the planner's check or bad input, its reason tallied: a start in contact, an end past the reach) or
failed (the physics, or any other exception).

Every `ok` run is checked from its timeseries.npz alone, independently of simbench's analysis (`promises_broken`):
the tool's distance from the line (point to segment) within analysis.path_tolerance, its last point within
goal_tolerance of the line's end, the plan's joints (q_ref) inside the ranges, its speeds (finite differences of
q_ref) within the speed limits, and no NaN anywhere. An `ok` run that breaks one is a bug of simbench's.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import re  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from importlib.metadata import distribution  # noqa: E402
from pathlib import Path  # noqa: E402

import dm_control  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402

import simbench  # noqa: E402
from benchmarks.bench_arms import CAUSES  # noqa: E402
from benchmarks.common import segment_distance  # noqa: E402
from simbench.core.errors import ScenarioError  # noqa: E402
from simbench.scenario.robot_mapping import load_robot  # noqa: E402
from simbench.scenario.schema import Units  # noqa: E402

LINES = 100
SEED = 35
LENGTHS = (0.05, 0.3)  # m
SPEED = 0.1  # m/s: the line's length over its duration
MIN_DURATION = 1.0  # s
HOLD = 0.3  # s
FLOOR_CLEARANCE = 0.05  # m: the tool's start and end above the floor (z = 0)
MARGIN = 0.1  # of each joint range's width, kept clear at either end


def jaco_robot() -> str:
    """The Jaco's robot mapping (degrees, millimetres), its MJCF found in dm_control's package folder."""
    model = Path(dm_control.__file__).parent / "third_party" / "kinova" / "jaco_arm.xml"
    return f"{{model: {model}, tool: {{site: wristsite}}, speed_limits: [36, 36, 36, 48, 48, 48]}}"


def _urdf(path: str) -> Path:
    """A URDF of the example-robot-data distribution, by its path under robots/."""
    return Path(str(distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data"))) / \
        "robots" / path


def ur5_robot() -> str:
    """The UR5's robot mapping (millimetres); the tool is the tool0 flange on wrist_3_link, the speed limits the
    URDF's."""
    model = _urdf("ur_description/urdf/ur5_robot.urdf")
    return f"{{model: {model}, tool: {{body: wrist_3_link, offset: [0, 82.3, 0]}}}}"


def xarm7_robot() -> str:
    """The xArm7's robot mapping: its URDF's one chain end (link_eef), the speed limits the URDF's."""
    return f"{{model: {_urdf('xarm_description/urdf/xarm7.urdf')}}}"


def z1_robot() -> str:
    """The Z1's robot mapping: its six arm joints to the gripper's stator (the gripper's own joint left out)."""
    return (f"{{model: {_urdf('z1_description/urdf/z1.urdf')}, tool: {{body: gripperStator}}, "
            "joints: [joint1, joint2, joint3, joint4, joint5, joint6]}")


ARMS = {"jaco": jaco_robot, "ur5": ur5_robot, "xarm7": xarm7_robot, "z1": z1_robot}


def scenario_text(robot: str, start_deg, end_mm, duration: float) -> str:
    """A cartesian_path scenario (degrees, millimetres): one line from the tool's point at `start_deg` to `end_mm`."""
    start = [round(float(v), 9) for v in start_deg]
    end = [round(float(v), 9) for v in end_mm]
    return (f"robot: {robot}\nplanner: cartesian_path\nunits: {{angle: deg, length: mm}}\n"
            f"task:\n  start: {start}\n  path:\n    - line: {{end: {end}}}\n"
            f"timing: {{duration: {duration:.6f}, hold: {HOLD}}}\n")


def load(text: str, folder: Path, name: str) -> simbench.Scenario:
    """The scenario of `text`, written to folder/name.yaml and loaded."""
    path = folder / f"{name}.yaml"
    path.write_text(text)
    return simbench.load_scenario(path)


def draw_lines(robot_def, n: int, seed: int = SEED) -> list[dict]:
    """n random lines on `robot_def`: start (deg), start and end tool points (mm), duration (s) (the module's
    docstring)."""
    rng = np.random.default_rng(seed)
    low = np.where(np.isfinite(robot_def.lower), robot_def.lower, -np.pi)
    high = np.where(np.isfinite(robot_def.upper), robot_def.upper, np.pi)
    width = high - low
    lines = []
    while len(lines) < n:
        q = rng.uniform(low + MARGIN * width, high - MARGIN * width)
        start = robot_def.fk(q[None])[0]
        direction = rng.normal(size=3)
        length = rng.uniform(*LENGTHS)
        end = start + length * direction / np.linalg.norm(direction)
        if min(start[2], end[2]) < FLOOR_CLEARANCE:
            continue
        lines.append({"index": len(lines), "start_deg": np.rad2deg(q), "from_mm": start * 1e3, "end_mm": end * 1e3,
                      "length_mm": length * 1e3, "duration": max(MIN_DURATION, length / SPEED)})
    return lines


def promises_broken(series, scenario: simbench.Scenario) -> tuple[list[str], dict]:
    """The promises an `ok` run's timeseries (an npz's arrays, SI) breaks, and the figures checked: the tool
    within path_tolerance of the line, ending within goal_tolerance of its end, q_ref inside the joint ranges and
    its finite-difference speeds within the speed limits, no NaN."""
    robot, analysis = scenario.robot_def, scenario.analysis
    a = robot.fk(np.array([scenario.task.start]))[0]
    b = np.array(scenario.task.path[0].line.end)
    tool, q_ref, t = series["tool"], series["q_ref"], series["t"]
    figures = {"deviation": float(segment_distance(tool, a, b).max()),
               "goal_error": float(np.linalg.norm(tool[-1] - b)),
               "range_excess": float(np.max(np.maximum(robot.lower - q_ref, q_ref - robot.upper))),
               "speed_ratio": float(np.max(np.abs(np.diff(q_ref, axis=0)) / np.diff(t)[:, None] / robot.qd_max))}
    nan = [name for name in series.files if series[name].dtype.kind == "f" and np.isnan(series[name]).any()]
    broken = [name for name, bad in (("path_tolerance", not figures["deviation"] <= analysis.path_tolerance),
                                     ("goal_tolerance", not figures["goal_error"] <= analysis.goal_tolerance),
                                     ("joint_range", not figures["range_excess"] <= 0.0),
                                     ("speed_limit", not figures["speed_ratio"] <= 1.0 + 1e-9)) if bad]
    return broken + [f"nan:{name}" for name in nan], figures


def run_line(robot: str, line: dict, folder: Path) -> dict:
    """Run one line without video into `folder`; its outcome, and for an `ok` run the independent checks."""
    name = f"line{line['index']:03d}"
    row = {"index": line["index"], "length_mm": line["length_mm"]}
    try:
        scenario = load(scenario_text(robot, line["start_deg"], line["end_mm"], line["duration"]), folder, name)
        result = simbench.run(scenario, folder / name, video=False)
    except ScenarioError as err:
        return {**row, "outcome": "refused", "reason": str(err).split(": ", 1)[-1]}
    except Exception as err:  # noqa: BLE001: a failure of any kind is counted, named by its type and message
        return {**row, "outcome": "failed", "reason": f"{type(err).__name__}: {err}"}
    report = result.report
    row.update(outcome=report["status"], kinds=sorted({v["kind"] for v in report["violations"]}))
    row["causes"] = sorted(cause for cause, members in CAUSES.items() if set(row["kinds"]) & set(members))
    row["from_start"] = any(v["kind"] == "actuator_saturation" and v["t"] <= report["timestep"]
                            for v in report["violations"])
    if report["status"] == "ok":
        with np.load(folder / name / "timeseries.npz") as series:
            row["broken"], row["figures"] = promises_broken(series, scenario)
    return row


def run_arm(arm: str, n: int = LINES, seed: int = SEED) -> list[dict]:
    """n random lines on `arm` (a key of ARMS), each run and checked."""
    robot = ARMS[arm]()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        probe = load_robot(yaml.safe_load(robot), "bench_random_lines", Units(angle="deg", length="mm"))
        return [run_line(robot, line, folder) for line in draw_lines(probe, n, seed)]


def measure(n: int = LINES) -> dict:
    """Every line of both arms."""
    out = {}
    for arm in ARMS:
        start = time.perf_counter()
        out[arm] = {"rows": run_arm(arm, n), "seconds": time.perf_counter() - start}
    return out


def _reason(text: str) -> str:
    """A refusal's reason without what varies from line to line (its figures), so that alike ones tally together."""
    return re.sub(r"-?\d+(\.\d+)?", "#", text)


def _tally(counter: Counter) -> str:
    return ", ".join(f"{key} {count}" for key, count in counter.most_common()) or "none"


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    lines = [
        "### Random lines on arms from their MJCF and URDF (issues 35 and 44)",
        "",
        f"`python -m benchmarks.run bench_random_lines`: {LINES} random lines per arm (seed {SEED}), `cartesian_path`, "
        f"run by `simbench.run` without video: starts uniform within the joint ranges ({MARGIN:.0%} of each width "
        f"clear of its ends), ends {LENGTHS[0] * 1e3:.0f}-{LENGTHS[1] * 1e3:.0f} mm from the start's tool point in "
        f"a random direction, both at least {FLOOR_CLEARANCE * 1e3:.0f} mm above the floor, at {SPEED * 1e3:.0f} "
        f"mm/s (at least {MIN_DURATION:g} s). Every `ok` run checked from its timeseries.npz alone: the tool within "
        "path_tolerance of the line (point to segment), its end within goal_tolerance, q_ref inside the ranges, "
        "its finite-difference speeds within the limits, no NaN.",
        "",
        "| arm | ok | limits | refused | failed | limits by cause (runs) | saturated from t = 0 | violation kinds "
        "(runs) | ok runs breaking a promise | worst ok deviation mm | worst ok goal error mm | highest ok speed / "
        "limit | s |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    notes = []
    for arm, result in r.items():
        rows = result["rows"]
        outcomes = Counter(row["outcome"] for row in rows)
        kinds = Counter(kind for row in rows for kind in row.get("kinds", ()))
        causes = Counter(cause for row in rows for cause in row.get("causes", ()))
        ok = [row for row in rows if row["outcome"] == "ok"]
        broken = [row for row in ok if row["broken"]]
        worst = {key: max((row["figures"][key] for row in ok), default=float("nan"))
                 for key in ("deviation", "goal_error", "speed_ratio")}
        lines.append(f"| {arm} | {outcomes['ok']} | {outcomes['limits']} | {outcomes['refused']} | "
                     f"{outcomes['failed']} | {_tally(causes)} | {sum(row.get('from_start', 0) for row in rows)} | "
                     f"{_tally(kinds)} | {len(broken)} | "
                     f"{worst['deviation'] * 1e3:.3f} | "
                     f"{worst['goal_error'] * 1e3:.3f} | {worst['speed_ratio']:.4f} | {result['seconds']:.0f} |")
        reasons = Counter(_reason(row["reason"]) for row in rows if row["outcome"] in ("refused", "failed"))
        if reasons:
            notes.append(f"- {arm}, refused or failed: " + "; ".join(f"{why} ({n})" for why, n in reasons.items()))
        notes += [f"- {arm}, line {row['index']} (seed {SEED}) ended `ok` but breaks {', '.join(row['broken'])}: "
                  + ", ".join(f"{k} {v:.6g}" for k, v in row["figures"].items()) for row in broken]
    return "\n".join(lines + ([""] + notes if notes else []))


if __name__ == "__main__":
    print(markdown(measure()))

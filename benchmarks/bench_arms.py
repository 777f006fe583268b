"""`simbench bench` on seven arms nobody here modelled (issue 44): example-robot-data's UR5, UR10, Panda, xArm7, Z1 and
SO-100, read from their installs untouched, and dm-control's Jaco, TASKS tasks each at seed SEED by METHODS, through
the whole pipeline (`simbench.commands.bench.run_bench`, WORKERS worker processes). time_scaling is left out: its
exact inverse
kinematics takes minutes a run on these arms (a UR5 line's Newton steps), an hour for the suite on two cores. Each arm
is mapped as a
user maps it: its URDF and a tool (the UR's `tool0` flange, the Panda's `panda_link8`, the Z1's gripper stator with
its six arm joints, the SO-100's gripper body with its five arm joints), nothing else.

Beside each robot and method's ok share and deviation, every run's verdict split by cause: each kind of violation
its run reports (report.json's, in runs.csv's `error`, `kind: message` each) counted once per run under one of
CAUSES; runs that did not get a verdict are `bad_input` (a refused task: a start in contact, say) or `run_failed`.
A run can count under more than one cause. `from t = 0` counts the runs whose actuator saturates from the first
sample: the set-up's doing (a start in contact, an unstable servo), not the method's. Run it with another simbench
on the path (PYTHONPATH) to measure that one: it reads nothing but runs.csv.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import csv  # noqa: E402
import re  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from collections import Counter  # noqa: E402
from importlib.metadata import distribution  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402

TASKS = 12
SEED = 0
WORKERS = 2
METHODS = ["dls_adaptive", "pinv", "dls", "mink"]
# The verdict's violation kinds by what caused them, in the table's order.
CAUSES = {"force": ("actuator_saturation", "force_limit"), "contact": ("contact",),
          "speed": ("velocity_limit", "acceleration_limit"), "range": ("joint_limit",),
          "off path": ("off_path", "goal_missed", "reference_jump"), "orientation": ("orientation_error",)}
_KIND = re.compile(r"(?:^|; )([a-z_]+): ")
_FROM_START = re.compile(r"(?:^|; )actuator_saturation: [^;]* from t = 0\.000 s")


def suite_text() -> str:
    """The suite file: the seven arms, TASKS tasks at SEED."""
    robots = Path(str(distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data")))
    urdf = robots / "robots"
    arms = [
        ("ur5", urdf / "ur_description/urdf/ur5_robot.urdf", "{body: tool0}", ""),
        ("ur10", urdf / "ur_description/urdf/ur10_robot.urdf", "{body: tool0}", ""),
        ("xarm7", urdf / "xarm_description/urdf/xarm7.urdf", "{body: link_eef}", ""),
        ("z1", urdf / "z1_description/urdf/z1.urdf", "{body: gripperStator}",
         "[joint1, joint2, joint3, joint4, joint5, joint6]"),
        ("so100", urdf / "so_arm_description/urdf/so100.urdf", "{body: gripper}",
         "[shoulder_pan, shoulder_lift, elbow_flex, wrist_flex, wrist_roll]"),
    ]
    lines = [f"name: arms\ntasks: {TASKS}\nseed: {SEED}\nrobots:", "  - panda", "  - jaco"]
    for name, model, tool, joints in arms:
        lines.append(f"  - {{name: {name}, model: {model}, tool: {tool}" + (f", joints: {joints}" if joints else "")
                     + "}")
    return "\n".join(lines) + "\n"


def kinds(error: str) -> set[str]:
    """The violation kinds of a runs.csv `error` cell (`kind: message; kind: message`)."""
    return set(_KIND.findall(error or ""))


def causes(row: dict) -> set[str]:
    """The causes (CAUSES' keys, or 'other') of a limits run's violations."""
    found = kinds(row["error"])
    named = {cause for cause, members in CAUSES.items() if found & set(members)}
    return named | ({"other"} if found - {k for members in CAUSES.values() for k in members} else set())


def table(runs: Path) -> list[dict]:
    """Per robot and method: runs, statuses, each cause's runs, and the ok runs' deviation p95 (mm)."""
    with open(runs, newline="") as f:
        rows = list(csv.DictReader(f))
    out = []
    for key in dict.fromkeys((r["robot"], r["method"]) for r in rows):
        group = [r for r in rows if (r["robot"], r["method"]) == key]
        status = Counter(r["status"] for r in group)
        cause = Counter(c for r in group if r["status"] == "limits" for c in causes(r))
        cause["from t = 0"] = sum(bool(_FROM_START.search(r["error"] or "")) for r in group)
        deviation = [float(r["deviation_max_mm"]) for r in group if r["deviation_max_mm"] not in ("", None)]
        orientation = [float(r["orientation_max_deg"]) for r in group if r.get("orientation_max_deg") not in ("", None)]
        out.append({"robot": key[0], "method": key[1], "runs": len(group), "status": status, "causes": cause,
                    "deviation_p95_mm": float(np.percentile(deviation, 95)) if deviation else None,
                    "orientation_p95_deg": float(np.percentile(orientation, 95)) if orientation else None})
    return out


def measure(tasks: int = TASKS, workers: int = WORKERS) -> dict:
    """The bench of the seven arms, run into a temporary folder; its table."""
    from simbench.commands.bench import load_suite, run_bench
    from simbench.core.errors import ScenarioError

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "arms.yaml"
        path.write_text(suite_text())
        start = time.perf_counter()
        try:
            result = run_bench(load_suite(path).with_options(tasks=tasks, methods=METHODS), Path(tmp) / "out",
                               workers=workers)
        except ScenarioError as err:
            return {"refused": str(err)}
        return {"rows": table(Path(tmp) / "out" / "runs.csv"), "seconds": time.perf_counter() - start,
                "runs": result.summary["runs"]}


def _share(n: int, total: int) -> str:
    return f"{n / total:.2f}" if total else "-"


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    head = [f"### Seven arms nobody here modelled: limits split by cause ({TASKS} tasks an arm, seed {SEED})", ""]
    if "refused" in r:
        return "\n".join(head + [f"The bench was refused: {r['refused']}"])
    head += [f"`python -m benchmarks.run bench_arms`: {r['runs']} runs by {', '.join(METHODS)} in "
             f"{r['seconds']:.0f} s on {WORKERS} workers. "
             "Shares of each robot and method's runs; a cause's share counts the `limits` runs with at least one "
             "violation of that cause (force: actuator_saturation, force_limit; contact; speed: velocity_limit, "
             "acceleration_limit; range: joint_limit; off path: off_path, goal_missed, reference_jump; orientation: "
             "orientation_error). Deviation: the p95 of tracking.tool_max over the runs that were simulated, mm.",
             "",
             "| robot | method | runs | ok | limits | bad input | failed | force | (from t = 0) | contact | speed | "
             "range | off path | orientation | other | deviation p95 mm | orientation p95 deg |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for row in r["rows"]:
        n, status, cause = row["runs"], row["status"], row["causes"]
        failed = status["run_failed"] + status["crashed"]
        cells = [row["robot"], row["method"], str(n), _share(status["ok"], n), _share(status["limits"], n),
                 _share(status["bad_input"], n), _share(failed, n),
                 *(_share(cause[c], n) for c in ("force", "from t = 0", *list(CAUSES)[1:], "other")),
                 "-" if row["deviation_p95_mm"] is None else f"{row['deviation_p95_mm']:.3g}",
                 "-" if row["orientation_p95_deg"] is None else f"{row['orientation_p95_deg']:.3g}"]
        head.append("| " + " | ".join(cells) + " |")
    return "\n".join(head)


if __name__ == "__main__":
    if len(sys.argv) > 1:  # a bench folder already run: its table alone
        print(markdown({"rows": table(Path(sys.argv[1]) / "runs.csv"), "seconds": float("nan"),
                        "runs": sum(1 for _ in open(Path(sys.argv[1]) / "runs.csv")) - 1}))
    else:
        print(markdown(measure()))

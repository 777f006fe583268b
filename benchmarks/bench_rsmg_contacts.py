"""RSMG round robin on random motions (project issue 16): how many the general contact points schedule against
the paper's fixed three per arm, why each refused one is refused, and, in physics, how every motion scheduled with
general contacts runs.

Motions (rsmg_contacts.random_motions, fixed seed): turns about uniform random axes (1-5 turns either way) and
tumbles (1-3 spin turns about a random rotor axis precessing 0.5-2 turns about another), 6-30 s each on the
shipped trapezoidal law, the task's defaults otherwise. Each is planned with `contacts: general` and with
`contacts: fixed` (the plan's own verdict: ranges, speed limits, jumps); every one general contacts schedule is
then simulated, and its run read: the fewest arms gripping at any instant, the gripping gammas, the rotor's
largest error against its command, the type A and B events, the run's status. The same motions again at four
times the speed (a quarter of the duration, 1.5-7.5 s, up to about 930 deg/s): beyond the issue's range, where
general contacts too must refuse some, to show each refusal's reason and that what is scheduled still runs.
"""

from __future__ import annotations

import re
import sys
import time
from collections import Counter

import numpy as np

from simbench.commands.pipeline import check_plan, evaluate
from simbench.core.errors import RunError
from simbench.planners.rsmg_contacts import random_motions
from simbench.scenario import parse_scenario

MOTIONS = 60
SEED = 16
SETS = {"as drawn (6-30 s)": 1.0, "four times as fast (1.5-7.5 s)": 4.0}  # durations divided by
_FIXED_REASON = re.compile(r"round robin: (at t = [\d.]+ s )?(.*?);")


def _plan(doc: dict, contacts: str) -> dict:
    """The plan of one motion with the given contacts: scheduled or refused (and why), its status, re-grips, time."""
    doc = {**doc, "task": {**doc["task"], "contacts": contacts}}
    start = time.perf_counter()
    try:
        traj, verdict = check_plan(parse_scenario(doc, doc["name"]))
    except RunError as err:
        return {"scheduled": False, "reason": str(err), "seconds": time.perf_counter() - start}
    return {"scheduled": True, "status": verdict.status, "regrips": traj.info["grips"],
            "seconds": time.perf_counter() - start}


def _physics(doc: dict) -> dict:
    """The run of one motion with general contacts: what the issue asks of it."""
    ev = evaluate(parse_scenario(doc, doc["name"]))
    extra, series = ev.analysis.extra, ev.analysis.series
    held = series["gamma"][series["engaged"]]
    events = [e["kind"] for e in ev.analysis.singularity_events if e["kind"] in ("typeA", "typeB")]
    return {"status": ev.verdict.status, "fewest": int(series["engaged"].sum(axis=1).min()),
            "gamma": [float(np.rad2deg(held.min())), float(np.rad2deg(held.max()))],
            "rotor_error": float(np.rad2deg(extra["rotor_error_max"])), "ab_events": len(events),
            "closure_um": float(extra["closure_error_max"] * 1e6)}


def _motion(doc: dict) -> str:
    """One line: the motion and its duration."""
    m = doc["task"]["motion"]
    if m["kind"] == "turns":
        what = f"{m['turns']:+.2f} turns"
    else:
        what = f"tumble {m['spin_turns']:+.2f} spin / {m['precession_turns']:+.2f} precession turns"
    return f"{what} in {doc['timing']['duration']:.1f} s"


def measure_set(speedup: float) -> list[dict]:
    """Every motion, its durations divided by `speedup`: both plans, and the run of the general one."""
    rows = []
    for doc in random_motions(MOTIONS, SEED):
        doc["timing"]["duration"] = round(doc["timing"]["duration"] / speedup, 2)
        row = {"name": doc["name"], "motion": _motion(doc), "kind": doc["task"]["motion"]["kind"],
               "general": _plan(doc, "general"), "fixed": _plan(doc, "fixed")}
        if row["general"]["scheduled"]:
            row["physics"] = _physics(doc)
        rows.append(row)
        print(row, file=sys.stderr, flush=True)
    return rows


def measure() -> dict:
    return {"sets": {name: measure_set(speedup) for name, speedup in SETS.items()}}


def _fixed_reason(reason: str) -> str:
    """A fixed-contacts refusal without its time, arms and numbers: why."""
    found = _FIXED_REASON.search(reason)
    if not found:
        return reason
    why = re.sub(r"arm \d", "an arm", found.group(2))
    return re.sub(r"the four gripping arms \(.*?\) hold the rotor with a largest 3x3 minor of A of [\d.]+",
                  "the four gripping arms' largest 3x3 minor of A falls under det_a_min", why)


def _general_reason(reason: str) -> str:
    """A general-contacts refusal's binding limit, in a few words."""
    for key, short in (("joints' speed limit binds", "the joints' speed limit"), ("re-gripping binds", "re-grip time"),
                       ("neither", "|det A| and the band")):
        if key in reason:
            return short
    return reason


def _table(sets: dict) -> list[str]:
    """Scheduled and refused with each kind of contacts, per set."""
    lines = ["| motions | contacts | scheduled | plan within limits | refused | planning s, median | planning s, max |",
             "|---|---|---|---|---|---|---|"]
    for name, rows in sets.items():
        n = len(rows)
        for contacts in ("general", "fixed"):
            plans = [row[contacts] for row in rows]
            done = [p for p in plans if p["scheduled"]]
            seconds = np.array([p["seconds"] for p in plans])
            lines.append(f"| {name} | `{contacts}` | {len(done)} of {n} ({len(done) / n:.0%}) | "
                         f"{sum(p['status'] == 'ok' for p in done)} | {n - len(done)} | {np.median(seconds):.2f} | "
                         f"{seconds.max():.2f} |")
    return lines


def _physics_table(sets: dict) -> list[str]:
    """What the runs of every motion scheduled with general contacts showed, per set."""
    lines = ["| motions | runs | fewest arms gripping | gripping gamma (deg) | rotor error, max (deg) | "
             "runs over 1 deg | type A or B events | closure error, max (um) | status |",
             "|---|---|---|---|---|---|---|---|---|"]
    for name, rows in sets.items():
        ran = [row for row in rows if "physics" in row]
        if not ran:
            continue
        phys = [row["physics"] for row in ran]
        worst = max(ran, key=lambda row: row["physics"]["rotor_error"])
        statuses = Counter(p["status"] for p in phys)
        lines.append(
            f"| {name} | {len(ran)} | {min(p['fewest'] for p in phys)} | {min(p['gamma'][0] for p in phys):.1f} - "
            f"{max(p['gamma'][1] for p in phys):.1f} | {worst['physics']['rotor_error']:.3f} ({worst['motion']}) | "
            f"{sum(p['rotor_error'] > 1.0 for p in phys)} | {sum(p['ab_events'] for p in phys)} | "
            f"{max(p['closure_um'] for p in phys):.0f} | " + ", ".join(f"{k} {v}" for k, v in sorted(statuses.items()))
            + " |")
    return lines


def markdown(r: dict) -> str:
    """The result as a BENCHMARKS.md section."""
    sets = r["sets"]
    first = next(iter(sets.values()))
    lines = [f"### RSMG round robin: general contact points against the paper's fixed three on {len(first)} random "
             f"motions (seed {SEED}; planning times are wall times)", "", *_table(sets), ""]
    for name, rows in sets.items():
        fixed_why = Counter(_fixed_reason(row["fixed"]["reason"]) for row in rows if not row["fixed"]["scheduled"])
        refused = [row for row in rows if not row["general"]["scheduled"]]
        why = Counter(_general_reason(row["general"]["reason"]) for row in refused)
        lines += [f"Motions {name}: refused with the fixed three: "
                  + ("; ".join(f"{k} ({v})" for k, v in fixed_why.most_common()) or "none")
                  + f". Refused with general contacts: {len(refused)}"
                  + (" (the binding limit: " + ", ".join(f"{k} {v}" for k, v in why.most_common()) + "):"
                     if refused else "."), ""]
        lines += [f"- {row['name']} ({row['motion']}): {row['general']['reason']}" for row in refused]
        if refused:
            lines.append("")
    ran = [row for row in first if "physics" in row]
    regrips = Counter(min(row["general"]["regrips"], 10) for row in ran)
    lines += ["Every motion scheduled with general contacts, simulated:", "", *_physics_table(sets), "",
              "Re-grips a motion with general contacts (as drawn): " + ", ".join(
                  f"{'10 or more' if k == 10 else k}: {v}" for k, v in sorted(regrips.items()))
              + ". Turns about a fixed axis often need none: an arm can hold a point near the rotation axis, which "
                "barely moves, for the whole motion, as long as the four points together keep |det A| above the "
                "floor."]
    return "\n".join(lines)


if __name__ == "__main__":
    print(markdown(measure()))

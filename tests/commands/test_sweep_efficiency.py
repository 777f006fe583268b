"""What a sweep does to go faster changes none of its results. Its runs reuse the Plant of the run before in
their process (simbench.core.plant.reused_plants): the table must be the one that a Plant built for each run alone
gives, metric for metric, with model-affecting settings swept and with switches that edit the running model. Its
plots are drawn at once in forked processes: the same files, byte for byte, as drawn one after another."""

import numpy as np
import yaml

from simbench.commands.sweep import execute, load_sweep, run_sweep, table
from simbench.core.plant import Plant, reused_plants
from simbench.outputs.report import plain
from simbench.robots import rsmg
from simbench.robots.spherical_arm import ROBOT
from simbench.scenario import parse_scenario
from tests.conftest import scenario_file

_build = Plant._build


def fresh(document: dict) -> dict:
    """A run's outcome with a Plant built for it alone (no reuse in force in this process)."""
    return execute.run_variant(document, "fresh")


def test_reuse_keeps_the_last_plant_for_the_same_arguments_only():
    assert Plant.load(ROBOT) is not Plant.load(ROBOT)  # outside the block: a fresh copy each time
    with reused_plants():
        first = Plant.load(ROBOT, 0.001, kp=[100.0] * 4)
        assert Plant.load(ROBOT, 0.001, kp=[100.0] * 4) is first
        other = Plant.load(ROBOT, 0.002, kp=[100.0] * 4)
        assert other is not first and other.model.opt.timestep == 0.002
        assert Plant.load(ROBOT, 0.001, kp=[100.0] * 4) is not first  # only the last one is kept
    assert Plant.load(ROBOT, 0.001, kp=[100.0] * 4) is not first


def test_sweep_table_equals_fresh_plants_run_by_run(tmp_path):
    """Two workers, each reusing its Plant while the timestep (slowest) stays and building a new one when it
    changes: every row's status, error and metrics exactly as a fresh Plant gives them."""
    spec = {"base": "spherical_arm/case1", "outputs": "none", "grid": {"sim.timestep": [0.001, 0.002]},
            "random": {"samples": 3, "seed": 4, "params": {"timing.duration": {"uniform": [1.0, 2.0]},
                                                           "sim.kv": {"uniform": [[20] * 4, [40] * 4]}}}}
    path = tmp_path / "reuse.yaml"
    path.write_text(yaml.safe_dump(spec))
    sweep = load_sweep(path)
    table = run_sweep(sweep, tmp_path / "out", workers=2).table
    for i, variant in enumerate(sweep.variants):
        want = fresh(variant.document)
        assert (table["status"][i], table["error"][i]) == (want["status"], want["error"])
        assert want["metrics"] and {k: table[k][i] for k in want["metrics"]} == plain(want["metrics"])


def test_switched_runs_leave_the_kept_plant_as_built(monkeypatch):
    """The RSMG's electromagnets switch welds during a run, which edits the running model (eq_active0, eq_data,
    the disabled actuator groups): two runs on one kept Plant give what a fresh Plant gives, and the kept model
    is still as built (the plan's own switches at its start would hide an edited one from the metrics)."""
    document = yaml.safe_load(scenario_file("rsmg", "three_turns").read_text())
    document["timing"]["duration"], document["task"]["motion"]["turns"] = 4.0, 1
    want = fresh(document)
    assert want["status"] == "ok" and want["metrics"]["switch_events"] > 0
    sim = parse_scenario(document, "kept").sim
    args = (rsmg.ROBOT, sim.timestep, sim.kp, sim.kv, sim.force_limits, sim.gravity_compensation)
    built = []
    monkeypatch.setattr(Plant, "_build", lambda *a: built.append(a) or _build(*a))
    with reused_plants():
        outcomes = [execute.run_variant(document, "kept") for _ in range(2)]
        kept = Plant.load(*args).model
    assert len(built) == 1  # both runs and the load above had the one Plant
    for outcome in outcomes:
        assert (outcome["status"], outcome["error"], plain(outcome["metrics"])) == \
            (want["status"], want["error"], plain(want["metrics"]))
    model = Plant.load(*args).model
    assert kept.opt.disableactuator == model.opt.disableactuator
    for name in ("eq_active0", "eq_data", "body_gravcomp", "actuator_gainprm", "actuator_biasprm"):
        np.testing.assert_array_equal(getattr(kept, name), getattr(model, name), err_msg=name)


def test_plots_drawn_at_once_are_the_plots_drawn_in_turn(tmp_path):
    """Two metrics against a grid of two numeric parameters: two scatter figures and two heat maps, drawn here
    one by one, and here and in forked processes at once (2 or 3 at a time, each taking the next figure none has
    taken), in the same order and to the same bytes."""
    params = ["sim.timestep", "timing.duration"]
    columns = {"run": [0, 1, 2, 3], "sim.timestep": [0.001, 0.001, 0.002, 0.002],
               "timing.duration": [2.0, 3.0, 2.0, 3.0], "status": ["ok", "limits", "ok", "run_failed"],
               "tool_rms": [1e-4, 3e-4, 2e-4, None], "tool_max": [4e-4, 9e-4, 5e-4, None]}
    drawn = {w: table.write_plots(columns, params, params, ["tool_rms", "tool_max"], tmp_path / str(w), w)
             for w in (1, 2, 3)}
    assert drawn[1] == drawn[2] == drawn[3] and len(drawn[1][0]) == 4
    for name in drawn[1][0]:
        for w in (2, 3):
            assert (tmp_path / "1" / name).read_bytes() == (tmp_path / str(w) / name).read_bytes(), (name, w)

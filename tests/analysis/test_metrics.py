"""An outside metric (conftest.PEAK_SPEED: the joints' largest speeds and the samples measured), installed as a
package is, through an entry point: its figures in report.json under metrics.<name>, on the run's page, as columns
of a sweep's results.csv and of a comparison's rows, and in `simbench list` with its origin. The truth: the run's
own recorded speeds (timeseries.npz, the Recording), reduced by NumPy."""

import csv
import os
import subprocess
import sys

import numpy as np
import yaml

import simbench
from simbench.commands.compare import MethodRun, row, table_csv
from tests.conftest import PEAK_SPEED, scenario_file

CASE1 = scenario_file("spherical_arm", "case1")


def _installed(tmp_path) -> dict:
    """The metric's package installed in tmp_path (a module and its dist-info), with a second entry point that
    does not load; the environment of a command that sees them."""
    (tmp_path / "peakmetric.py").write_text(PEAK_SPEED)
    info = tmp_path / "peakmetric-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: peakmetric\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[simbench.metrics]\npeak_speed = peakmetric:PeakSpeed\n"
                                           "lost = peakmetric:Missing\n")
    return {**os.environ, "PYTHONPATH": str(tmp_path)}


def _simbench(env: dict, *args: str) -> subprocess.CompletedProcess:
    done = subprocess.run([sys.executable, "-P", "-m", "simbench", *args], env=env, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    return done


def test_an_outside_metric_from_an_entry_point_is_in_the_report_the_page_the_list_and_a_sweep(tmp_path):
    env = _installed(tmp_path)
    listed = _simbench(env, "list").stdout
    assert "peak_speed" in listed and "(entry point peakmetric:PeakSpeed (peakmetric))" in listed
    assert any(line.split()[:2] == ["lost", "BROKEN:"] for line in listed.splitlines())

    out = tmp_path / "run"
    _simbench(env, "run", str(CASE1), "--out", str(out), "--no-video", "--quiet")
    report = yaml.safe_load((out / "report.json").read_text())  # JSON is YAML
    with np.load(out / "timeseries.npz") as series:
        truth, samples = np.abs(series["qd"]).max(axis=0), len(series["t"])
    figures = report["metrics"]["peak_speed"]
    assert figures == {"qd0_max": truth[0], "qd_max": truth.tolist(), "samples": samples}
    assert "tool_rms" in report["tracking"] and "peak_speed" not in report["tracking"]
    page = (out / "index.html").read_text()
    assert "metrics.peak_speed" in page and f"{truth[0]:.4g}" in page and f"{truth[2]:.4g}" in page

    duration = yaml.safe_load(CASE1.read_text())["timing"]["duration"]
    spec = tmp_path / "sweep.yaml"
    spec.write_text(yaml.safe_dump({"base": "spherical_arm/case1", "grid": {"timing.duration": [duration,
                                                                                              2 * duration]}}))
    _simbench(env, "sweep", str(spec), "--out", str(tmp_path / "sweep"), "--workers", "1", "--quiet")
    with open(tmp_path / "sweep" / "results.csv") as f:
        rows = list(csv.DictReader(f))
    assert float(rows[0]["peak_speed.qd0_max"]) == truth[0]  # the same run as above
    assert yaml.safe_load(rows[0]["peak_speed.qd_max"]) == truth.tolist()
    assert int(rows[0]["peak_speed.samples"]) == samples and int(rows[1]["peak_speed.samples"]) > samples


def test_a_registered_metric_is_a_column_of_a_comparison(peak_speed):
    scenario = simbench.load_scenario(CASE1)
    ev = simbench.evaluate(scenario)
    found = row(MethodRun("case1", scenario.planner, "servo", scenario, ev.verdict.status, ev))
    truth = np.abs(ev.recording.qd).max(axis=0)
    assert (found["peak_speed.qd0_max"], found["peak_speed.qd_max"]) == (truth[0], truth.tolist())
    assert found["peak_speed.samples"] == ev.recording.t.size
    header = table_csv((found,)).splitlines()[0].split(",")
    assert {"peak_speed.qd0_max", "peak_speed.qd_max", "peak_speed.samples"} <= set(header)

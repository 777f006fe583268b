"""Code simbench does not own: a scenario's policy and an installed package's plugins.

A scenario is data: a policy named by a module path (`package.module:factory`) is imported only with
--allow-code (allow_code=True), and nothing of it runs before that check; a registered policy is named by its
name. Whatever user code raises, SystemExit and KeyboardInterrupt included, is that code's failure (bad input
for a factory, a failed run with its report mid-run, a broken plugin at import), while the process's own Ctrl-C
still interrupts. Each test's truth is an exit code, a file written or not, or a marker a module writes when it
is imported.
"""

import csv
import json
import os
import signal
import subprocess
import sys
import textwrap

import pytest
import yaml
from simbench_planar3r import control as planar3r_control

import simbench
from simbench import api
from simbench.api import registry
from simbench.cli import main
from tests.conftest import interrupt

PLANAR3R = planar3r_control.__file__.rsplit("/", 1)[0] + "/scenarios"
MARK = "open({marker!r}, 'a').write('imported\\n')\n"


def scenario(tmp_path, policy: str, name: str = "user") -> str:
    """A copy of the example's line, one second long, whose control is the policy named `policy`."""
    raw = yaml.safe_load(open(f"{PLANAR3R}/line_policy.yaml"))
    raw["control"] = {"controller": "policy", "policy": policy, "action": "torque"}
    raw["timing"]["duration"] = 1.0
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(raw))
    return str(path)


def module(tmp_path, name: str, body: str) -> str:
    """A module `name` in tmp_path that writes a marker file when imported; the marker's path."""
    marker = tmp_path / f"{name}.imported"
    (tmp_path / f"{name}.py").write_text(MARK.format(marker=str(marker)) + textwrap.dedent(body))
    return str(marker)


@pytest.fixture
def importable(tmp_path, monkeypatch):
    """tmp_path on sys.path, and the modules tests write there forgotten afterwards."""
    monkeypatch.syspath_prepend(str(tmp_path))
    before = set(sys.modules)
    yield
    for name in set(sys.modules) - before:
        if getattr(sys.modules[name], "__file__", "") and str(tmp_path) in sys.modules[name].__file__:
            del sys.modules[name]


def run_cli(args, capsys):
    code = main(args)
    out = capsys.readouterr()
    return code, out.out, out.err.strip().splitlines()


# --- a scenario is data --------------------------------------------------------------------------------------

ACT = "import numpy as np\n\ndef make(scenario):\n    return lambda obs: np.zeros(3)\n"


def act_zero(obs):
    """A registered policy's action: no torque."""
    return obs["q"] * 0.0


def main_list(capsys) -> str:
    """What `simbench list` prints."""
    assert main(["list"]) == 0
    return capsys.readouterr().out


def test_a_module_path_is_not_imported_without_allow_code(tmp_path, capsys, importable):
    marker = module(tmp_path, "userpolicy", ACT)
    path = scenario(tmp_path, "userpolicy:make")
    out = tmp_path / "out"
    code, _, lines = run_cli(["run", path, "--out", str(out), "--quiet", "--no-video"], capsys)
    assert code == 2 and len(lines) == 1 and lines[0].startswith(f"error: {path}: control.policy: ")
    assert "--allow-code" in lines[0]
    assert not os.path.exists(marker) and not out.exists()
    with pytest.raises(simbench.ScenarioError, match="allow_code=True"):
        simbench.run(path, out=out, video=False)
    assert not os.path.exists(marker)
    code, _, _ = run_cli(["run", path, "--out", str(out), "--quiet", "--no-video", "--allow-code"], capsys)
    assert code in (0, 3) and os.path.exists(marker) and (out / "report.json").is_file()


def test_this_prints_nothing_without_allow_code(tmp_path, capsys):
    """`policy: "this:x"` would print the Zen of Python the moment `this` is imported."""
    sys.modules.pop("this", None)
    path = scenario(tmp_path, "this:x")
    code, stdout, lines = run_cli(["run", path, "--out", str(tmp_path / "out"), "--quiet"], capsys)
    assert code == 2 and len(lines) == 1 and "Beautiful" not in stdout and "this" not in sys.modules


def test_validate_says_a_module_path_needs_allow_code_without_importing_it(tmp_path, capsys, importable):
    marker = module(tmp_path, "userpolicy", ACT)
    path = scenario(tmp_path, "userpolicy:make")
    code, stdout, _ = run_cli(["validate", path], capsys)
    assert code == 0 and "--allow-code" in stdout and not os.path.exists(marker)


def test_a_registered_policy_is_named_and_an_unknown_name_refused(tmp_path, capsys):
    registry.register_policy(api.PolicyFactory("zero_torque_test", "zero torques", lambda sc: act_zero))
    out = tmp_path / "out"
    code, _, _ = run_cli(["run", scenario(tmp_path, "zero_torque_test"), "--out", str(out), "--no-video",
                          "--quiet"], capsys)
    report = json.loads((out / "report.json").read_text())
    assert code in (0, 3) and report["control"]["policy"] == "zero_torque_test"
    assert "zero_torque_test" in main_list(capsys)
    path = scenario(tmp_path, "no_such_policy")
    code, _, lines = run_cli(["validate", "--no-plan", path], capsys)
    assert code == 2 and len(lines) == 1 and lines[0].startswith(f"error: {path}: control.policy: unknown policy")


def test_a_sweep_over_control_obeys_allow_code_per_variant(tmp_path, capsys, importable):
    marker = module(tmp_path, "userpolicy", ACT)
    base = scenario(tmp_path, "zero_torque_sweep_test")
    registry.register_policy(api.PolicyFactory("zero_torque_sweep_test", "zero torques", lambda sc: act_zero))
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(yaml.safe_dump({"base": os.path.basename(base),
                                     "grid": {"control.policy": ["userpolicy:make", "zero_torque_sweep_test"]}}))
    out = tmp_path / "out"
    assert main(["sweep", str(sweep), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    rows = list(csv.DictReader(open(out / "results.csv")))
    assert rows[0]["status"] == "bad_input" and "--allow-code" in rows[0]["error"]
    assert rows[1]["status"] in ("ok", "limits") and not os.path.exists(marker)


def test_compare_refuses_a_module_path_without_allow_code(tmp_path, capsys, importable):
    marker = module(tmp_path, "userpolicy", ACT)
    path = scenario(tmp_path, "userpolicy:make")
    code, _, lines = run_cli(["compare", path, "--planners", "dls_line", "--out", str(tmp_path / "out")], capsys)
    assert code == 2 and len(lines) == 1 and "--allow-code" in lines[0] and not os.path.exists(marker)
    assert lines[0].startswith(f"error: {path}: control.policy: ")  # the file, as run names it


def test_python_m_simbench_imports_nothing_from_the_current_folder(tmp_path):
    """A stray yaml.py where the command is started would shadow PyYAML."""
    marker = module(tmp_path, "yaml", "raise SystemExit('the stray yaml.py ran')\n")
    proc = subprocess.run([sys.executable, "-m", "simbench", "validate", "--no-plan",
                           f"{PLANAR3R}/line.yaml"], capture_output=True, text=True, cwd=tmp_path)
    assert proc.returncode == 0 and not os.path.exists(marker), proc.stderr


# --- what user code raises -----------------------------------------------------------------------------------

@pytest.mark.parametrize("raising, said", [("sys.exit()", "SystemExit"), ("sys.exit(4)", "SystemExit: 4"),
                                           ("raise KeyboardInterrupt", "KeyboardInterrupt")])
def test_a_factory_that_exits_is_bad_input(raising, said, tmp_path, capsys, importable):
    module(tmp_path, "userpolicy", f"import sys\n\ndef make(scenario):\n    {raising}\n")
    path = scenario(tmp_path, "userpolicy:make")
    out = tmp_path / "out"
    code, _, lines = run_cli(["run", path, "--out", str(out), "--quiet", "--allow-code"], capsys)
    assert (code, lines) == (2, [f"error: {path}: control.policy: userpolicy:make raised {said}"])
    assert not out.exists()


@pytest.mark.parametrize("raising, said", [("sys.exit(3)", "SystemExit: 3"),
                                           ("raise KeyboardInterrupt('mine')", "KeyboardInterrupt: mine")])
def test_a_policy_that_exits_mid_run_writes_its_report(raising, said, tmp_path, capsys, importable):
    """As a ValueError there does: exit 1, the report says the run failed and why."""
    module(tmp_path, "userpolicy", f"""\
        import sys
        import numpy as np

        def make(scenario):
            def act(obs):
                if obs['time'][0] > 0.5:
                    {raising}
                return np.zeros(3)
            return act
        """)
    out = tmp_path / "out"
    code, _, lines = run_cli(["run", scenario(tmp_path, "userpolicy:make"), "--out", str(out), "--quiet",
                              "--no-video", "--allow-code"], capsys)
    cause = f"controller 'policy' raised {said}"
    assert code == 1 and len(lines) == 1 and lines[0].startswith("run failed: control failed at t = 0.50")
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "failed" and report["failure"]["cause"] == cause


def test_the_process_own_ctrl_c_in_a_policy_still_interrupts(tmp_path):
    """The policy sends its own process SIGINT, as a press would: exit 130, no report written."""
    module(tmp_path, "userpolicy", """\
        import os, signal
        import numpy as np

        def make(scenario):
            def act(obs):
                if obs['time'][0] > 0.5:
                    os.kill(os.getpid(), signal.SIGINT)
                return np.zeros(3)
            return act
        """)
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "simbench", "run", scenario(tmp_path, "userpolicy:make"), "--out",
                           str(out), "--quiet", "--no-video", "--allow-code"], capture_output=True, text=True,
                          cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(tmp_path)},
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    assert (proc.returncode, proc.stderr) == (130, "interrupted\n") and not out.exists()


def test_a_sweep_on_one_worker_whose_policy_exits_has_its_rows(tmp_path, capsys, importable):
    module(tmp_path, "userpolicy", """\
        import sys
        import numpy as np

        def make(scenario):
            if scenario.timing.duration > 1.5:
                sys.exit()
            def act(obs):
                if obs['time'][0] > 0.5:
                    sys.exit(3)
                return np.zeros(3)
            return act
        """)
    base = scenario(tmp_path, "userpolicy:make")
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text(yaml.safe_dump({"base": os.path.basename(base), "grid": {"timing.duration": [1.0, 2.0]}}))
    out = tmp_path / "out"
    assert main(["sweep", str(sweep), "--out", str(out), "--workers", "1", "--quiet", "--allow-code"]) == 0
    rows = list(csv.DictReader(open(out / "results.csv")))
    assert [r["status"] for r in rows] == ["run_failed", "bad_input"]
    assert "raised SystemExit: 3" in rows[0]["error"] and rows[1]["error"].endswith("raised SystemExit")


# --- plugins -------------------------------------------------------------------------------------------------

def plugin(tmp_path, body: str) -> dict:
    """An installed package (its dist-info in tmp_path) whose entry point `ghost` in simbench.robots imports
    module `ghostplugin`, `body` at its top; the environment of a command that sees it."""
    (tmp_path / "ghostplugin.py").write_text(textwrap.dedent(body) + "ROBOT = None\n")
    info = tmp_path / "ghostplugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: ghostplugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[simbench.robots]\nghost = ghostplugin:ROBOT\n")
    return {**os.environ, "PYTHONPATH": str(tmp_path)}


def simbench_command(*args) -> list[str]:
    return [sys.executable, "-P", "-m", "simbench", *args]


def test_a_plugin_that_exits_at_import_is_listed_as_broken(tmp_path):
    env = plugin(tmp_path, "import sys\nsys.exit('no licence')\n")
    proc = subprocess.run(simbench_command("list"), capture_output=True, text=True, cwd=tmp_path, env=env)
    assert proc.returncode == 0, proc.stderr
    robots = proc.stdout.split("planners:")[0].splitlines()
    assert {"puma600", "planar3r"} <= {line.split()[0] for line in robots[1:] if line.strip()}
    broken = [line for line in robots if "ghost" in line]
    assert len(broken) == 1 and "SystemExit: no licence" in broken[0] and "ghostplugin:ROBOT" in broken[0]


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_a_plugin_that_hangs_at_import_can_be_stopped(signum, code, tmp_path, monkeypatch):
    marker = tmp_path / "ghostplugin.imported"
    monkeypatch.setenv("PYTHONPATH", plugin(tmp_path, MARK.format(marker=str(marker))
                                            + "import time\nwhile True:\n    time.sleep(1)\n")["PYTHONPATH"])
    done = interrupt(simbench_command("list"), marker.exists, tmp_path, signum=signum)
    assert (done.returncode, done.stderr) == (code, "interrupted\n")


def test_a_plugin_that_raises_keyboard_interrupt_is_broken_not_an_interrupt(tmp_path):
    env = plugin(tmp_path, "raise KeyboardInterrupt('not a press')\n")
    proc = subprocess.run(simbench_command("list"), capture_output=True, text=True, cwd=tmp_path, env=env)
    assert proc.returncode == 0 and "KeyboardInterrupt: not a press" in proc.stdout, proc.stderr

"""A model's own actuators as simbench keeps or adds servos beside them (robots.model_scene), on a 3-joint arm
written here: a position servo the file gives, named or not, is kept with the file's gains and said so on its
joint's line of `simbench inspect`; the joints without one get servos designed for them, on their own lines, as the
same arm without any actuator gets them; an actuator on a tendon over the chain's joints is replaced as any that
is not the joint's own servo (it fought the servos: the tool 208 mm off); and the arm runs."""

import json
import re

import pytest

from simbench.cli import main

ARM = """<mujoco model="arm3">
  <worldbody>
    <body name="base" pos="0 0 0.1">
      <geom type="cylinder" size="0.05 0.05"/>
      <body name="l1" pos="0 0 0.05">
        <joint name="j1" axis="0 0 1" range="-170 170"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.2" size="0.03"/>
        <body name="l2" pos="0 0 0.2">
          <joint name="j2" axis="0 1 0" range="-90 90"/>
          <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
          <body name="l3" pos="0.3 0 0">
            <joint name="j3" axis="0 1 0" range="-150 150"/>
            <geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.025"/>
            <site name="tip" pos="0.25 0 0"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
  {actuators}
</mujoco>
"""


def _lines(tmp_path, capsys, name: str, actuators: str) -> dict[str, str]:
    """`simbench inspect`'s actuator line of each joint, of the arm with `actuators`."""
    path = tmp_path / f"{name}.xml"
    path.write_text(ARM.replace("{actuators}", actuators))
    assert main(["inspect", str(path)]) == 0
    out = capsys.readouterr().out
    section = out.split("actuators (", 1)[1].split("force limits:", 1)[0]
    return {m.group(1): m.group(2) for m in re.finditer(r"^  (j\d)\s+(.*)$", section, re.MULTILINE)}


@pytest.mark.parametrize("servo, kp, kv", [('<position joint="j2" kp="300" kv="10"/>', "300", "10"),
                                           ('<position name="p2" joint="j2" kp="100"/>', "100", "0")])
def test_a_servo_the_file_gives_is_kept_on_its_own_joint(tmp_path, capsys, servo, kp, kv):
    bare = _lines(tmp_path, capsys, "bare", "")
    kept = _lines(tmp_path, capsys, "kept", f"<actuator>{servo}</actuator>")
    assert kept["j2"].startswith(f"kept its position servo kp {kp}, kv {kv} ")
    for joint in ("j1", "j3"):  # designed for their own joint, as on the arm without any actuator
        assert kept[joint] == bare[joint] and re.search(r"added a position servo, kp [\d.]+, kv [\d.]+", kept[joint])


def test_an_arm_whose_servo_has_no_name_runs(tmp_path, capsys):
    """An unnamed actuator (MuJoCo allows it) gets a force sensor all the same: the scenario plans, simulates and
    scores (its status one of a run's, not an internal error)."""
    (tmp_path / "arm.xml").write_text(ARM.replace("{actuators}",
                                                  '<actuator><position joint="j2" kp="300" kv="10"/></actuator>'))
    (tmp_path / "move.yaml").write_text(
        "planner: joint_move\nunits: {angle: deg, length: mm}\n"
        "robot: {model: arm.xml, tool: {site: tip}, speed_limits: [90, 90, 90]}\n"
        "timing: {law: quintic, duration: 2.0, hold: 0.2}\ntask: {start: [0, 20, -40], goal: [30, 30, -60]}\n")
    code = main(["run", str(tmp_path / "move.yaml"), "--out", str(tmp_path / "out"), "--no-video", "--quiet"])
    assert code in (0, 3), capsys.readouterr().err
    assert (tmp_path / "out" / "report.json").is_file()


TENDON = ('<tendon><fixed name="t23"><joint joint="j2" coef="1"/><joint joint="j3" coef="-1"/></fixed></tendon>'
          '<actuator><position name="tp" tendon="t23" kp="500"/></actuator>')


def test_a_servo_on_a_tendon_over_the_chain_is_replaced_and_the_arm_tracks(tmp_path, capsys):
    """The tendon's servo moves j2 and j3 (MuJoCo's actuator moment): each is said replaced by a servo designed as
    on the bare arm, the tendon's taken off the scene; a joint move then ends ok, the tool within 1 mm of its plan."""
    bare = _lines(tmp_path, capsys, "bare", "")
    lines = _lines(tmp_path, capsys, "tendon", TENDON)
    for joint in ("j2", "j3"):
        said = "position servo 'tp' (on a tendon that moves it) replaced by a position servo, "
        assert lines[joint] == said + bare[joint].removeprefix("no actuator: added a position servo, ")
    assert lines["j1"] == bare["j1"]
    (tmp_path / "move.yaml").write_text(
        "planner: joint_move\nunits: {angle: deg, length: mm}\n"
        "robot: {model: tendon.xml, tool: {site: tip}, speed_limits: [180, 180, 180]}\n"
        "timing: {law: quintic, duration: 1.0, hold: 0.2}\ntask: {start: [0, 20, -40], goal: [60, 40, -80]}\n")
    assert main(["run", str(tmp_path / "move.yaml"), "--out", str(tmp_path / "out"), "--no-video", "--quiet"]) == 0
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["tracking"]["tool_max"] < 1e-3


@pytest.mark.parametrize("integrator, said", [("RK4", "rk4"), ("implicit", "implicit"),
                                              ("implicitfast", "implicitfast")])
def test_inspect_names_the_models_integrator(tmp_path, capsys, integrator, said):
    """The integrator line names the file's integrator as MuJoCo spells it (it lost its first letter: `mplicit`)."""
    path = tmp_path / "arm.xml"
    option = f'<mujoco model="arm3"><option integrator="{integrator}"/>'
    path.write_text(ARM.replace("{actuators}", "").replace('<mujoco model="arm3">', option))
    assert main(["inspect", str(path)]) == 0
    assert f"integrator: {said} (the model's)" in capsys.readouterr().out

"""The resolved-rate loop's per-sample shortcuts (planners/resolved_rates) give what the general computations give,
bit for bit, on random inputs (fixed seeds):

  - an arm with no joint to spare skips the null-space projector: its rates equal those with the projection of a
    zero preference added (the sign of a zero rate included), held joints and all; and the projector a rule's basis
    makes is I - Ju+ Ju with NumPy's own pseudo-inverse;
  - one rotation pair's orientation error is the batch's row, and the cross-product sum of its definition (Siciliano
    et al. 2009, eq. 3.85);
  - a control sample's kinematics (ModelArm.pose_jacobian_at) are the batch's row (ModelArm.pose_jacobian), and
    its Jacobian's position rows the finite differences of the tool point.
"""

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from simbench.commands.bench import load_suite
from simbench.planners.path_methods import damped_rates, null_projector, pinv_rates, resolver_of
from simbench.planners.resolved_rates import _clamped_rates, orientation_error

RULES = {"pinv": pinv_rates, "dls_adaptive": damped_rates, "dls": resolver_of("dls", None).rule}
DT = 0.001


def _jacobians(rng, count: int, rows: int, dof: int):
    """Random Jacobians, one in three near a rank loss (a column nearly another's)."""
    for i in range(count):
        ju = rng.normal(size=(rows, dof))
        if i % 3 == 0:
            ju[:, -1] = ju[:, 0] + 1e-3 * rng.normal(size=rows)
        yield ju


@pytest.mark.parametrize("rule", RULES)
def test_an_arm_with_no_joint_to_spare_gets_the_rates_the_projection_of_zero_gives(rule):
    rng = np.random.default_rng(7)
    robot = SimpleNamespace(lower=-np.full(6, 1.0), upper=np.full(6, 1.0))
    held_seen = 0
    for i, ju in enumerate(_jacobians(rng, 60, 6, 6)):
        twist = rng.normal(size=6) * (0.0 if i % 5 == 0 else 1.0)  # a zero twist: zero rates of either sign
        now = rng.uniform(-0.5, 0.5, 6)
        if i % 2:  # half of them with joints at a range's end, held where their rates leave it
            now[::2] = np.sign(rng.normal(size=3)) * (1 - 1e-7)
        spared = _clamped_rates(ju, twist, now, None, robot, DT, RULES[rule])
        general = _clamped_rates(ju, twist, now, np.zeros(6), robot, DT, RULES[rule])
        assert spared[0].tobytes() == general[0].tobytes(), i
        assert spared[1:3] == general[1:3] and np.array_equal(spared[3], general[3]), i
        held_seen += int(np.count_nonzero(spared[3]) > 0)
    assert held_seen > 5


@pytest.mark.parametrize("rule", RULES)
def test_a_rules_basis_makes_numpys_null_space_projector(rule):
    rng = np.random.default_rng(8)
    for ju in _jacobians(rng, 30, 6, 7):
        basis = RULES[rule](ju, rng.normal(size=6))[3]
        assert np.allclose(null_projector(basis), np.eye(7) - np.linalg.pinv(ju) @ ju, atol=1e-9)


def test_one_pairs_orientation_error_is_the_batchs_row_and_its_definition():
    goals, turned = (Rotation.random(50, random_state=seed).as_matrix() for seed in (1, 2))
    batch = orientation_error(goals, turned)
    for goal, r, row in zip(goals, turned, batch):
        one = orientation_error(goal, r)
        assert one.tobytes() == row.tobytes()
        defined = 0.5 * sum(np.cross(r[:, c], goal[:, c]) for c in range(3))  # n x n_d + s x s_d + a x a_d
        assert np.allclose(one, defined, atol=1e-15)


def test_a_samples_kinematics_are_the_batchs_row_and_the_points_derivative():
    arm = load_suite("puma600").robots[0].model_arm()
    rng = np.random.default_rng(9)
    q = arm.lower + (arm.upper - arm.lower) * rng.uniform(0.1, 0.9, (20, arm.dof))
    points, rotations, jacobians = arm.pose_jacobian(q)
    for k, row in enumerate(q):
        point, rotation, jac = arm.pose_jacobian_at(row)
        assert point.tobytes() == points[k].tobytes() and rotation.tobytes() == rotations[k].tobytes()
        assert np.ascontiguousarray(jac).tobytes() == jacobians[k].tobytes()
        step = 1e-6 * np.eye(arm.dof)
        moved = (arm.pose(row + step)[0] - arm.pose(row - step)[0]) / 2e-6  # (dof, 3)
        assert np.allclose(jac[:3], moved.T, atol=1e-7)

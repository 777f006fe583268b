"""Lines, arcs and composite paths: geometry against closed-form truths."""

import numpy as np
import pytest

from simbench.maths.paths import Arc, Composite, Line

S = np.linspace(0, 1, 1001)


def test_line_points_length_and_tangent():
    line = Line(np.array([0.1, 0.2, 0.3]), np.array([0.4, -0.2, 0.3]))
    assert line.length == pytest.approx(0.5)
    p = line.point(S)
    assert np.allclose(p[0], line.p0) and np.allclose(p[-1], line.p1)
    assert np.allclose(np.diff(p, axis=0) / np.diff(S)[:, None], line.tangent(S)[1:])


@pytest.mark.parametrize("normal", [[0, 0, 1], [1, 1, 0], [0.3, -0.2, 0.9]])
def test_arc_lies_on_its_circle(normal):
    arc = Arc.from_plane([0.1, 0.0, 0.5], 0.12, normal, 0.3, 0.3 + 2 * np.pi)
    p = arc.point(S)
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    assert np.allclose(np.linalg.norm(p - arc.center, axis=1), 0.12)
    assert np.allclose((p - arc.center) @ n, 0.0)
    assert np.allclose(p[0], p[-1])
    assert arc.length == pytest.approx(2 * np.pi * 0.12)
    assert np.allclose(np.linalg.norm(arc.tangent(S), axis=1), arc.length)
    fd = np.gradient(p, S, axis=0)
    assert np.abs(fd[1:-1] - arc.tangent(S)[1:-1]).max() < 1e-3


def test_composite_is_continuous_and_at_constant_speed():
    a = np.array([0.3, -0.2, 0.4])
    b = np.array([0.3, 0.0, 0.4])
    arc = Arc.from_plane(b + [0.0, 0.0, 0.1], 0.1, [1, 0, 0], 0.0, np.pi, ref=[0, 0, -1])  # starts at b
    assert np.allclose(arc.point(np.array([0.0]))[0], b)
    end = arc.point(np.array([1.0]))[0]
    seam = Composite((Line(a, b), arc, Line(end, end + [0.0, 0.2, 0.0])))
    p = seam.point(np.linspace(0, 1, 20001))
    steps = np.linalg.norm(np.diff(p, axis=0), axis=1)
    assert steps.max() == pytest.approx(seam.length / 20000, rel=1e-3)
    assert seam.length == pytest.approx(0.2 + np.pi * 0.1 + 0.2)
    assert np.allclose(np.linalg.norm(seam.tangent(S), axis=1), seam.length)

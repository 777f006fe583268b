"""Infinite planes drawn finite (simbench.outputs.drawn_planes): which sizes change inside the block, and that all
come back.
How the drawn floor looks against MuJoCo's endless one: test_env_copy_render."""

import mujoco
import numpy as np
import pytest

from simbench.outputs.drawn_planes import TILES, planes_drawn_finite

SCENE = """
<mujoco>
  <statistic extent="2" center="0 0 0"/>
  <visual><map zfar="30"/></visual>
  <worldbody>
    <geom name="endless" type="plane" size="0 0 0.05"/>
    <geom name="half" type="plane" size="0 3 0.5" pos="0 0 1"/>
    <geom name="square" type="plane" size="2 2 0.1" pos="0 0 2"/>
    <geom name="box" type="box" size="0.1 0.2 0.3"/>
  </worldbody>
</mujoco>
"""


def test_only_infinite_sides_are_drawn_to_the_far_clip_and_all_sizes_come_back():
    """An infinite side becomes the far clipping distance (zfar x extent = 60 m), its grid spacing 2 x 60 / TILES
    (or the plane's own, where coarser); finite planes and other geoms keep their sizes; all are back after the
    block, also when it raises."""
    model = mujoco.MjModel.from_xml_string(SCENE)
    before = model.geom_size.copy()
    far = 30 * 2
    with planes_drawn_finite(model):
        inside = model.geom_size.copy()
    np.testing.assert_array_equal(model.geom_size, before)
    np.testing.assert_allclose(inside[0], [far, far, 2 * far / TILES])
    np.testing.assert_allclose(inside[1], [far, 3, 2 * far / TILES])
    np.testing.assert_array_equal(inside[2:], before[2:])
    with pytest.raises(RuntimeError), planes_drawn_finite(model):
        raise RuntimeError("a frame failed")
    np.testing.assert_array_equal(model.geom_size, before)

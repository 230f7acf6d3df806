"""The simulated depth camera: noise and quantisation that grow with distance as the sensor model says,
holes at depth edges and out of range, the same reading from the same seed."""

from __future__ import annotations

import numpy as np
import pytest

from hoap_actions.errors import InvalidInputError
from hoap_actions.vision.depth_sensor import DepthSensor


def test_noise_grows_with_distance_as_the_model_says():
    sensor = DepthSensor(disparity_step_px=0.0, dropout=0.0)
    rng = np.random.default_rng(0)
    for z in (0.8, 1.5, 3.0):
        reading = sensor.measure(np.full((200, 200), z), rng)
        a, b, c = sensor.noise_m
        assert np.std(reading - z) == pytest.approx(a + b * (z - c) ** 2, rel=0.05)
        assert abs(np.mean(reading - z)) < 0.1 * (a + b * (z - c) ** 2)


def test_depth_comes_in_steps_that_grow_with_distance():
    """Disparity quantised to 1/8 px: every reading is focal_baseline / (k / 8) for a whole k, the nearest
    such depth to the truth, and the steps grow with the square of the distance."""
    sensor = DepthSensor(noise_m=(0.0, 0.0, 0.4), dropout=0.0, edge_jump_m=1.0)
    widths = []
    for z in (1.0, 2.0):
        true = np.linspace(z, z + 0.05, 400).reshape(20, 20)
        reading = sensor.measure(true, np.random.default_rng(1))
        k = sensor.focal_baseline / reading / sensor.disparity_step_px
        np.testing.assert_allclose(k, np.round(k), atol=1e-6)
        step = z**2 * sensor.disparity_step_px / sensor.focal_baseline
        assert np.all(np.abs(reading - true) <= 0.6 * step * ((z + 0.05) / z) ** 2)
        widths.append(np.diff(np.unique(reading)).mean())
    assert widths[1] / widths[0] == pytest.approx(4.0, rel=0.15)


def test_holes_at_depth_edges_out_of_range_and_only_there():
    depth = np.full((40, 40), 1.2)
    depth[:, 20:] = 1.6  # a step of 40 cm: a depth edge down the middle
    depth[0, 0] = 0.2  # nearer than the sensor measures
    reading = DepthSensor(dropout=0.0).measure(depth, np.random.default_rng(2))
    holes = np.isnan(reading)
    assert holes[:, 19].all() and holes[:, 20].all()  # both sides of the edge
    assert holes[0, 0]
    holes[:, 19:21] = False
    holes[0, 0] = holes[0, 1] = holes[1, 0] = False  # the too-near pixel's neighbours see a jump too
    assert not holes.any()


def test_same_seed_same_reading_and_bad_sensors_refused():
    depth = np.random.default_rng(3).uniform(0.8, 2.0, (30, 40))
    sensor = DepthSensor()
    np.testing.assert_array_equal(sensor.measure(depth, np.random.default_rng(7)),
                                  sensor.measure(depth, np.random.default_rng(7)))
    for bad in ({"dropout": 1.0}, {"edge_jump_m": 0.0}, {"range_m": (2.0, 1.0)}, {"disparity_step_px": -1.0}):
        with pytest.raises(InvalidInputError, match="depth sensor"):
            DepthSensor(**bad)
    with pytest.raises(InvalidInputError, match="H, W"):
        sensor.measure(np.ones((2, 3, 3)), np.random.default_rng(0))

"""The table-top scene: geometry measured on the loaded bodies, peg-in-hole physics, layouts, cameras."""

from __future__ import annotations

import math

import numpy as np
import pytest
from matplotlib.path import Path

from hoap_actions.envs import world
from hoap_actions.envs.scene import (
    BOARD_SIZE,
    BOARD_YAW_RANGE,
    CHAMFER,
    FOREARM_HEADING_TOLERANCE,
    FOREARM_LENGTH,
    FOREARM_STRIP_HALF_WIDTH,
    HOLE_LOCAL_XY,
    HOLE_SIZE,
    N_HOLES,
    PEG_COLOURS,
    PEG_LENGTH,
    PEG_MASS,
    PEG_RADIUS,
    Layout,
    Scene,
)
from hoap_actions.envs.sim import Sim
from hoap_actions.errors import InvalidInputError

# A board turned 0.2 rad (so "across" and "along" are not the world axes), pegs out of the way.
TURNED = Layout(
    board_xy=(0.03, -0.01),
    board_yaw=0.2,
    peg_xy=((-0.04, -0.07), (-0.04, 0.0), (-0.04, 0.07)),
    hole_of_peg=(0, 1, 2),
)


@pytest.fixture
def scene():
    sim = Sim()
    yield Scene(sim)
    sim.close()


def board_axes(scene: Scene) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (2,) across and along the board's hole row, in the table plane."""
    _, yaw = scene.board_pose()
    return np.array([math.cos(yaw), math.sin(yaw)]), np.array([-math.sin(yaw), math.cos(yaw)])


def peg_axis_and_bottom(scene: Scene, i: int) -> tuple[np.ndarray, np.ndarray]:
    pos, (x, y, z, w) = scene.peg_pose(i)
    axis = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    return axis, pos - 0.5 * PEG_LENGTH * axis


def tilt_deg(scene: Scene, i: int) -> float:
    axis, _ = peg_axis_and_bottom(scene, i)
    return math.degrees(math.acos(min(1.0, axis[2])))


def seconds(scene: Scene, t: float) -> int:
    return round(t / scene.sim.timestep)


# ------------------------------------------------------------------------------------ geometry
def test_peg_size_and_mass_measured(scene):
    scene.apply(TURNED)
    (x, y, _), _ = scene.peg_pose(0)
    mid = PEG_LENGTH / 2
    starts = [(x + 0.05, y, mid), (x - 0.05, y, mid), (x, y + 0.05, mid), (x, y - 0.05, mid), (x, y, 0.2)]
    points, names = scene.sim.ray_cast(starts, [(x, y, mid)] * 4 + [(x, y, -0.01)])
    assert names == [scene.peg_names[0]] * 5
    radii = np.hypot(points[:4, 0] - x, points[:4, 1] - y)
    np.testing.assert_allclose(radii, 0.0075, atol=5e-5)  # 15 mm across, exactly: implicit cylinder
    assert points[4, 2] == pytest.approx(0.05, abs=1e-4)  # 50 mm tall, standing on the table
    mass, _ = scene.sim.mass_properties(scene.peg_names[0])
    assert mass == pytest.approx(PEG_MASS)


def test_holes_clearance_depth_and_chamfer_measured(scene):
    scene.apply(TURNED)
    sim = scene.sim
    across, along = board_axes(scene)
    holes = scene.hole_positions()
    assert holes.shape == (N_HOLES, 3)
    np.testing.assert_allclose(holes[:, 2], scene.board_surface_z)
    peg_diameter = 0.015
    for hole in holes:
        # walls: rays from the hole's axis, below the chamfer, out to the four walls
        centre = np.r_[hole[:2], 0.01]
        ends = [centre + 0.05 * np.r_[d, 0.0] for d in (across, -across, along, -along)]
        points, names = sim.ray_cast([centre] * 4, ends)
        assert names == ["hole_board"] * 4
        half = np.linalg.norm(points[:, :2] - hole[:2], axis=1)
        widths = np.array([half[0] + half[1], half[2] + half[3]])
        np.testing.assert_allclose(widths, HOLE_SIZE, atol=1e-4)
        clearance = widths - peg_diameter  # 2 mm in all, 1 mm a side
        assert np.all((0.001 - 5e-5 <= clearance) & (clearance <= 0.002 + 5e-5))

        # depth: straight down the hole's axis the first thing hit is the table top
        points, names = sim.ray_cast([hole + (0, 0, 0.05)], [hole - (0, 0, 0.1)])
        assert names == ["table"] and points[0, 2] == pytest.approx(0.0, abs=1e-4)
        depth = hole[2] - points[0, 2]
        assert 0.5 * PEG_LENGTH <= depth < PEG_LENGTH  # an inserted peg stands, and still shows 25 mm to grasp

        # chamfer: rays square to a 45-degree plane from the wall top to the surface meet it all along
        # (rays that graze a tilted box's vertex are not exact in Bullet, so none is cast that way)
        fractions = np.linspace(0.1, 0.9, 9)[:, None]
        for direction in (across, -along):
            on_plane = np.c_[
                hole[:2] + (HOLE_SIZE / 2 + fractions * CHAMFER) * direction,
                hole[2] - CHAMFER + fractions[:, 0] * CHAMFER,
            ]
            normal = np.r_[-direction, 1.0] / math.sqrt(2.0)  # out of the chamfer, into the hole's mouth
            points, names = sim.ray_cast(on_plane + 0.006 * normal, on_plane - 0.002 * normal)
            assert set(names) == {"hole_board"}
            np.testing.assert_allclose(points, on_plane, atol=1e-4)
            # just inside the wall line the hole is open to the table; just beyond the mouth, the flat top
            xy = hole[:2] + np.array([HOLE_SIZE / 2 - 3e-4, HOLE_SIZE / 2 + CHAMFER + 3e-4])[:, None] * direction
            points, names = sim.ray_cast(np.c_[xy, [0.05, 0.05]], np.c_[xy, [-0.01, -0.01]])
            assert names == ["table", "hole_board"]
            np.testing.assert_allclose(points[:, 2], [0.0, scene.board_surface_z], atol=1e-4)


def test_table_and_floor_match_world(scene):
    sim = scene.sim
    x0, x1 = world.TABLE_NEAR_EDGE_X, world.TABLE_NEAR_EDGE_X + world.TABLE_SIZE[0]
    y1 = world.TABLE_SIZE[1] / 2
    inside = [(x0 + 0.003, -y1 + 0.003), (x1 - 0.003, y1 - 0.003), (x0 + 0.003, y1 - 0.003), (x1 - 0.003, -y1 + 0.003)]
    outside = [(x0 - 0.003, 0.0), (x1 + 0.003, 0.0), (0.07, y1 + 0.003), (0.07, -y1 - 0.003)]
    xy = np.array(inside + outside)
    points, names = sim.ray_cast(np.c_[xy, np.full(8, 0.5)], np.c_[xy, np.full(8, -1.0)])
    assert names == ["table"] * 4 + ["floor"] * 4
    np.testing.assert_allclose(points[:4, 2], 0.0, atol=1e-4)
    np.testing.assert_allclose(points[4:, 2], world.FLOOR_Z, atol=1e-4)
    low, high = sim.aabb("table")
    assert low[2] == pytest.approx(world.FLOOR_Z, abs=2e-3)  # legs reach the floor


# ------------------------------------------------------------------------------ peg in hole
DROPS = [
    # (offset from the hole centre in mm, what happens)
    (0.0, "in"),
    (1.0, "in"),  # within the 1 mm clearance
    (2.5, "in"),  # beyond the clearance, on the chamfer: slides in
    (3.0, "in"),
    (4.0, "out"),  # beyond the chamfer: lands on the rim and tips over
    (8.0, "out"),
    (14.0, "on board"),  # centre of mass over the flat top: stays standing on the board
]


@pytest.mark.parametrize("direction", ["across", "along"])
@pytest.mark.parametrize("offset_mm, outcome", DROPS, ids=[f"{o}mm-{r.replace(' ', '-')}" for o, r in DROPS])
def test_peg_dropped_from_1cm_over_a_hole(scene, direction, offset_mm, outcome):
    scene.apply(TURNED)
    across, along = board_axes(scene)
    hole = scene.hole_positions()[1]
    xy = hole[:2] + offset_mm * 1e-3 * (across if direction == "across" else along)
    scene.sim.set_base_pose(scene.peg_names[0], (*xy, scene.board_surface_z + 0.01 + PEG_LENGTH / 2))
    scene.sim.step(seconds(scene, 1.5))
    _, bottom = peg_axis_and_bottom(scene, 0)
    assert scene.peg_in_hole(0, 1) is (outcome == "in")
    assert not scene.peg_in_hole(0, 0) and not scene.peg_in_hole(0, 2)
    if outcome == "in":
        assert bottom[2] == pytest.approx(0.0, abs=5e-4)  # seated on the table top
        assert tilt_deg(scene, 0) < 3.0
    elif outcome == "out":
        # not even jammed in the hole at a slant: the bottom is outside the hole or above its opening
        assert not scene.peg_in_hole(0, 1, tilt_tol_deg=90.0, min_depth=0.0)
    else:
        assert bottom[2] == pytest.approx(scene.board_surface_z, abs=5e-4) and tilt_deg(scene, 0) < 1.0


def test_peg_in_hole_checks_footprint_depth_and_tilt(scene):
    scene.apply(TURNED)
    across, _ = board_axes(scene)
    hole = scene.hole_positions()[2]

    def place(xy, bottom_z, tilt=0.0):
        axis = np.array([0.0, -math.sin(tilt), math.cos(tilt)])  # tilted about world x
        centre = np.r_[xy, bottom_z] + 0.5 * PEG_LENGTH * axis
        scene.sim.set_base_pose(scene.peg_names[0], centre, (math.sin(tilt / 2), 0.0, 0.0, math.cos(tilt / 2)))

    place(hole[:2], 0.0)
    assert [scene.peg_in_hole(0, j) for j in range(N_HOLES)] == [False, False, True]
    place(hole[:2] + 0.008 * across, 0.0)  # bottom still inside the 8.5 mm half-width
    assert scene.peg_in_hole(0, 2)
    place(hole[:2] + 0.009 * across, 0.0)
    assert not scene.peg_in_hole(0, 2)
    place(hole[:2], 0.02)  # only 5 mm in
    assert not scene.peg_in_hole(0, 2) and scene.peg_in_hole(0, 2, min_depth=0.004)
    place(hole[:2], 0.0, tilt=math.radians(15.0))
    assert not scene.peg_in_hole(0, 2) and scene.peg_in_hole(0, 2, tilt_tol_deg=20.0)
    with pytest.raises(InvalidInputError, match="accepted"):
        scene.peg_in_hole(0, N_HOLES)


# ----------------------------------------------------------------------------------- layouts
def check_layout(layout: Layout, n_pegs: int) -> None:
    """Independent checks: sampled points of the board's outline, not the library's distance code."""
    low, high = world.WORK_AREA_LOW, world.WORK_AREA_HIGH
    board = np.array(layout.board_xy)
    pegs = np.array(layout.peg_xy)
    assert pegs.shape == (n_pegs, 2)
    assert np.all((low <= board) & (board <= high))
    assert np.all((low <= pegs) & (pegs <= high))
    assert BOARD_YAW_RANGE[0] <= layout.board_yaw <= BOARD_YAW_RANGE[1]
    c, s = math.cos(layout.board_yaw), math.sin(layout.board_yaw)
    hx, hy = BOARD_SIZE[0] / 2, BOARD_SIZE[1] / 2
    t = np.linspace(-1.0, 1.0, 101)
    local = np.r_[np.c_[hx * t, np.full(101, hy)], np.c_[hx * t, np.full(101, -hy)],
                  np.c_[np.full(101, hx), hy * t], np.c_[np.full(101, -hx), hy * t]]  # fmt: skip
    outline = board + local @ np.array([[c, s], [-s, c]])
    assert outline[:, 0].min() >= world.TABLE_NEAR_EDGE_X
    assert outline[:, 0].max() <= world.TABLE_NEAR_EDGE_X + world.TABLE_SIZE[0]
    assert np.abs(outline[:, 1]).max() <= world.TABLE_SIZE[1] / 2
    for i, peg in enumerate(pegs):
        assert np.linalg.norm(outline - peg, axis=1).min() >= 0.04 - 1e-4  # outline sampled every <= 1.1 mm
        peg_local = np.array([[c, s], [-s, c]]) @ (peg - board)
        assert not (abs(peg_local[0]) <= hx and abs(peg_local[1]) <= hy)  # not on the board
        for other in pegs[:i]:
            assert np.linalg.norm(peg - other) >= 0.04
    assert len(set(layout.hole_of_peg)) == n_pegs and set(layout.hole_of_peg) <= set(range(N_HOLES))
    holes = board + HOLE_LOCAL_XY @ np.array([[c, s], [-s, c]])
    assert np.all(Path(world.HAND_REACH_XY).contains_points(holes, radius=-1e-9)), "a hole out of the hand's reach"
    for i, grasped in enumerate(pegs):
        back = (world.FOREARM_PIVOT_XY - grasped) / np.linalg.norm(world.FOREARM_PIVOT_XY - grasped)
        side = np.array([-back[1], back[0]])
        far = FOREARM_STRIP_HALF_WIDTH + FOREARM_HEADING_TOLERANCE * FOREARM_LENGTH
        strip = Path([grasped + FOREARM_STRIP_HALF_WIDTH * side, grasped + FOREARM_LENGTH * back + far * side,
                      grasped + FOREARM_LENGTH * back - far * side, grasped - FOREARM_STRIP_HALF_WIDTH * side])
        others = np.delete(pegs, i, axis=0)
        assert not np.any(strip.contains_points(others)), f"a peg stands where the forearm grasps peg {i}"


def test_200_sampled_layouts_are_valid_and_varied(scene):
    rng = np.random.default_rng(2024)
    layouts = [scene.sample_layout(rng) for _ in range(200)]
    for layout in layouts:
        check_layout(layout, 3)
    boards = np.array([layout.board_xy for layout in layouts])
    yaws = np.array([layout.board_yaw for layout in layouts])
    assert boards[:, 0].min() < -0.03 and boards[:, 0].max() > 0.03  # both sides of the work area
    assert np.ptp(boards[:, 1]) > 0.12 and np.ptp(yaws) > 0.8
    assert len({layout.hole_of_peg for layout in layouts}) == 6  # every assignment of 3 pegs to 3 holes


def test_same_seed_same_layout_different_seeds_differ(scene):
    first = scene.sample_layout(np.random.default_rng(7))
    assert scene.sample_layout(np.random.default_rng(7)) == first
    other_sim = Sim()
    try:
        assert Scene(other_sim).sample_layout(np.random.default_rng(7)) == first  # no hidden state in the scene
    finally:
        other_sim.close()
    layouts = [scene.sample_layout(np.random.default_rng(seed)) for seed in range(20)]
    assert len({(lay.board_xy, lay.peg_xy) for lay in layouts}) == 20


def test_fewer_pegs_and_bad_peg_counts():
    sim = Sim()
    try:
        scene = Scene(sim, n_pegs=2)
        assert scene.peg_names == ["peg_red", "peg_green"]
        check_layout(scene.sample_layout(np.random.default_rng(0)), 2)
        with pytest.raises(InvalidInputError, match="accepted"):
            Scene(sim, n_pegs=4)
    finally:
        sim.close()


def test_applied_pegs_stand_still_for_a_second(scene):
    rng = np.random.default_rng(5)
    for _ in range(3):  # each layout starts from the previous one's final state
        layout = scene.sample_layout(rng)
        scene.apply(layout)
        scene.sim.step(seconds(scene, 1.0))
        for i, (x, y) in enumerate(layout.peg_xy):
            pos, _ = scene.peg_pose(i)
            assert np.linalg.norm(pos - (x, y, PEG_LENGTH / 2)) < 1e-3
            assert tilt_deg(scene, i) < 0.5
        centre, yaw = scene.board_pose()
        np.testing.assert_allclose(centre, layout.board_xy, atol=1e-9)
        assert yaw == pytest.approx(layout.board_yaw)


def test_apply_refuses_layouts_that_would_collide(scene):
    pegs = TURNED.peg_xy
    bad = {
        "overlap": Layout(TURNED.board_xy, 0.0, (pegs[0], (pegs[0][0] + 0.01, pegs[0][1]), pegs[2]), (0, 1, 2)),
        "overlaps the board": Layout(TURNED.board_xy, 0.0, (TURNED.board_xy, pegs[1], pegs[2]), (0, 1, 2)),
        "overhangs": Layout((world.TABLE_NEAR_EDGE_X, 0.0), 0.0, pegs, (0, 1, 2)),
        "distinct": Layout(TURNED.board_xy, 0.0, pegs, (0, 0, 2)),
        "scene has 3": Layout(TURNED.board_xy, 0.0, pegs[:2], (0, 1)),
    }
    for message, layout in bad.items():
        with pytest.raises(InvalidInputError, match=message):
            scene.apply(layout)


# ----------------------------------------------------------------------------------- cameras
def test_overhead_camera_sees_every_peg_and_hole(scene):
    camera = scene.sim.cameras["overhead"]
    board_id = scene.sim.body_id("hole_board")
    rng = np.random.default_rng(11)
    for _ in range(3):
        scene.apply(scene.sample_layout(rng))
        image = scene.sim.render("overhead")
        assert image.rgb.shape == (camera.height, camera.width, 3)
        for i, name in enumerate(scene.peg_names):
            body = scene.sim.body_id(name)
            assert (image.segmentation == body).sum() >= 80  # the 15 mm top face alone is ~12 px across
            top, _ = scene.peg_pose(i)
            u, v = camera.project(top + (0, 0, PEG_LENGTH / 2))[0].astype(int)
            assert image.segmentation[v, u] == body
            colour = np.array(PEG_COLOURS[name.removeprefix("peg_")][:3])
            assert np.argmax(image.rgb[v, u]) == np.argmax(colour)  # red, green or blue dominates
        across, _ = board_axes(scene)
        for hole in scene.hole_positions():
            u, v = camera.project(hole - (0, 0, hole[2]))[0].astype(int)  # the hole's floor, seen from above
            assert image.segmentation[v, u] == board_id
            assert image.rgb[v - 1 : v + 2, u - 1 : u + 2].mean() < 60  # a dark square ...
            u, v = camera.project(np.r_[hole[:2] + 0.016 * across, hole[2]])[0].astype(int)
            assert image.rgb[v, u].mean() > 150  # ... in a light board


def test_front_camera_sees_the_table_and_board(scene):
    scene.apply(TURNED)
    image = scene.sim.render("front")
    segmentation = image.segmentation
    assert (segmentation == scene.sim.body_id("table")).mean() > 0.15
    assert (segmentation == scene.sim.body_id("hole_board")).sum() > 100
    assert image.depth.min() > 0.3  # the camera stands clear of the table, across from the robot


def test_a_peg_asleep_on_the_table_drops_where_it_is_put_and_wakes_when_touched(scene):
    """Resting pegs sleep (Sim.let_sleep: asleep, a peg's pose does not change by a bit): teleported, one
    wakes and drops into a hole; touched by another peg, one wakes and is pushed aside (a sleeping body
    would stay where it was)."""
    scene.apply(TURNED)
    scene.sim.step(seconds(scene, 3.0))  # Bullet sends bodies at rest for 2 s to sleep
    asleep = np.concatenate(scene.peg_pose(1))
    scene.sim.step(seconds(scene, 0.5))
    np.testing.assert_array_equal(np.concatenate(scene.peg_pose(1)), asleep)  # awake, it creeps by ~1e-7 m
    hole = scene.hole_positions()[1]
    scene.sim.set_base_pose(scene.peg_names[0], (*hole[:2], scene.board_surface_z + 0.01 + PEG_LENGTH / 2))
    scene.sim.step(seconds(scene, 1.5))
    assert scene.peg_in_hole(0, 1)
    resting, _ = scene.peg_pose(1)
    # the other peg put 3 mm into the resting one, beside it on the table: the contact pushes both apart
    scene.sim.set_base_pose(scene.peg_names[2], (resting[0] + 2 * PEG_RADIUS - 0.003, resting[1], resting[2]))
    scene.sim.step(seconds(scene, 0.5))
    assert np.linalg.norm(scene.peg_pose(1)[0] - resting) > 1e-3


def _holes_from_the_sim(scene: Scene) -> np.ndarray:
    """The hole openings computed from a fresh read of the board's pose (no cache)."""
    pos, (_, _, z, w) = scene.sim.base_pose("hole_board")
    yaw = 2.0 * math.atan2(z, w)
    xy = pos[:2] + HOLE_LOCAL_XY @ np.array([[math.cos(yaw), math.sin(yaw)], [-math.sin(yaw), math.cos(yaw)]])
    return np.column_stack([xy, np.full(N_HOLES, BOARD_SIZE[2])])


def test_holes_follow_the_board_however_it_is_moved(scene):
    """The board's pose is read once per placement, not per step: every way of moving it is seen."""
    first = scene.hole_positions()
    np.testing.assert_allclose(first, _holes_from_the_sim(scene), atol=1e-12)
    saved = scene.sim.save_state()
    scene.sim.step(10)  # stepping leaves a fixed-base board where it is
    np.testing.assert_array_equal(scene.hole_positions(), first)
    scene.apply(scene.sample_layout(np.random.default_rng(3)))
    moved = scene.hole_positions()
    assert np.abs(moved - first).max() > 0.01
    np.testing.assert_allclose(moved, _holes_from_the_sim(scene), atol=1e-12)
    scene.sim.set_base_pose("hole_board", (0.25, 0.05, BOARD_SIZE[2] / 2), (0.0, 0.0, math.sin(0.2), math.cos(0.2)))
    centre, yaw = scene.board_pose()
    np.testing.assert_allclose([*centre, yaw], [0.25, 0.05, 0.4], atol=1e-9)
    np.testing.assert_allclose(scene.hole_positions(), _holes_from_the_sim(scene), atol=1e-12)
    scene.sim.restore_state(saved)
    np.testing.assert_array_equal(scene.hole_positions(), first)
    scene.hole_positions()[:] = 0.0  # a caller's copy: the next read is unchanged
    np.testing.assert_array_equal(scene.hole_positions(), first)

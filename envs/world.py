"""Where things stand: one place for the table, the robot's placement and the work area.

World frame: z up, origin on the table top at the centre of the work area, x away from the robot.
The robot, the scene and the tasks all read these numbers, so they always agree.
"""

from __future__ import annotations

import numpy as np

TABLE_HEIGHT = 0.26  # m, floor to table top: the floor is the plane z = -TABLE_HEIGHT
TABLE_NEAR_EDGE_X = -0.08  # m, the table edge facing the robot
TABLE_SIZE = (0.30, 0.50, 0.02)  # m, depth (x), width (y), top thickness
ROBOT_FEET_XY = (-0.18, 0.05)  # m, midpoint between the robot's ankles on the floor; it faces +x
FIXED_LEGS_FEET_XY = (-0.21, 0.10)
"""m, where the robot with welded legs stands: 3 cm further back and 5 cm further left than the
free-standing one, which reaches near and across by moving its pelvis. Bolted where the other stands,
the right hand could not come within reach of the near edge (elbow at its bend limit) nor across to the
far left (shoulder roll and yaw at theirs): 26 of 50 validation layouts for the scripted expert; here 46
(50 once the hand controller waited 1 s for this robot's IK, see ``UNREACHED_TICKS_FIXED_LEGS``)."""
WORK_AREA_LOW = np.array([-0.05, -0.09])  # m, (x, y) corner of the area where pegs and holes lie
WORK_AREA_HIGH = np.array([0.05, 0.09])

# Where the right hand can work from above (tcp 7 cm over the table, the peg axis vertical), measured
# with the whole-body IK's reachability probe on a 1 cm grid and shrunk by 1 cm; tests/test_scene.py
# checks it against the IK. The far left corner is out of reach: the right arm must cross the body.
HAND_REACH_XY = np.array(
    [[-0.07, -0.15], [0.12, -0.15], [0.12, 0.03], [0.09, 0.06], [0.07, 0.08], [0.04, 0.10], [0.02, 0.11], [-0.07, 0.11]]
)  # m, convex polygon, counter-clockwise
# The right forearm, over a peg it grasps from above, points back towards about this point (the
# IK's hand headings over the work area: 6 degrees rms, at most 20 degrees off, measured).
FOREARM_PIVOT_XY = np.array(ROBOT_FEET_XY) + np.array([0.043, -0.114])

FLOOR_Z = -TABLE_HEIGHT


# ==================== human demonstration scene <-> robot scene (envs/demo_scene.py) ====================
# The human scene uses the same axis convention, origin on ITS table top at the centre of the paper's
# 80 x 30 cm active region (x away from the demonstrator, y to their left, z up). As in the paper, marker
# and object locations are rescaled to the robot: one uniform scale and one offset, nothing else,
#     p_robot = HUMAN_TO_ROBOT_SCALE * p_human + HUMAN_TO_ROBOT_OFFSET.
# The scale maps the active region's width onto the work area's width (0.80 m -> 0.18 m, so its depth
# 0.30 m -> 0.0675 m fits the 0.10 m deep work area); the offset puts the region's centre on the work
# area's centre, both table tops at z = 0.
HUMAN_ACTIVE_REGION_SIZE = (0.30, 0.80)  # m, depth (x) and width (y) of the active region (paper: 80 x 30 cm)
HUMAN_TO_ROBOT_SCALE = float((WORK_AREA_HIGH - WORK_AREA_LOW)[1] / HUMAN_ACTIVE_REGION_SIZE[1])
HUMAN_TO_ROBOT_OFFSET = np.array([*((WORK_AREA_LOW + WORK_AREA_HIGH) / 2.0), 0.0])


def human_to_robot(points: np.ndarray) -> np.ndarray:
    """Human-scene points (..., 3) in metres to robot-scene points (..., 3)."""
    return HUMAN_TO_ROBOT_SCALE * np.asarray(points, float) + HUMAN_TO_ROBOT_OFFSET


def robot_to_human(points: np.ndarray) -> np.ndarray:
    """Robot-scene points (..., 3) in metres to human-scene points (..., 3); inverse of :func:`human_to_robot`."""
    return (np.asarray(points, float) - HUMAN_TO_ROBOT_OFFSET) / HUMAN_TO_ROBOT_SCALE

"""Where things stand: one place for the table, the robot's placement and the work area.

World frame: z up, origin on the table top at the centre of the work area, x away from the robot.
The robot, the scene and the tasks all read these numbers, so they always agree.
"""

from __future__ import annotations

import numpy as np

TABLE_HEIGHT = 0.26  # m, floor to table top: the floor is the plane z = -TABLE_HEIGHT
TABLE_NEAR_EDGE_X = -0.08  # m, the table edge facing the robot
TABLE_SIZE = (0.30, 0.50, 0.02)  # m, depth (x), width (y), top thickness
ROBOT_FEET_XY = (-0.15, 0.05)  # m, midpoint between the robot's ankles on the floor; it faces +x
WORK_AREA_LOW = np.array([-0.05, -0.09])  # m, (x, y) corner of the area where pegs and holes lie
WORK_AREA_HIGH = np.array([0.05, 0.09])

FLOOR_Z = -TABLE_HEIGHT

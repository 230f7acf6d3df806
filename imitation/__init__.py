"""Learning actions from observations, end to end: a demonstration seen through a camera and the robot
doing the same thing to its own block (``hoap_actions/Imitate-v0``)."""

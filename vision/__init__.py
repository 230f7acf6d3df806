"""What cameras see: the pegs and holes on the robot's table, and the demonstrator's edges, silhouette,
body contour and block in the demonstration world's images."""

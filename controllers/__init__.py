"""From a desired hand path to joint commands: retiming (ruckig), whole-body IK (placo), perception, policies."""

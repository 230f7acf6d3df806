"""Policies for any ``env.step`` loop: the scripted expert, the robot acting with its learned models
(the paper's Fig. 9), the execution layer they share, and the registry the command line reads."""

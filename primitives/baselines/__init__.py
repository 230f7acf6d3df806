"""What a robot-learning reader compares the parametric HMMs with: movement primitives (ProMP, DMP, GMR)
for synthesis and per-class HMMs or a frame-wise classifier for recognition, from well-kept libraries
behind the project's estimator contract."""

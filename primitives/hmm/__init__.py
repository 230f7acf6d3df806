"""HMM maths and the parametric HMMs: densities, forward-backward, Viterbi, the PHMM estimator, its
file format, its hyper-parameter selection, and the posture model."""

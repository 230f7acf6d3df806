"""Learning and recognising action primitives: HMM maths, discovery, grammar, parametric HMMs, tracking."""

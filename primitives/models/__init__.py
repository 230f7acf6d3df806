"""Learned action models: one PHMM per discovered class with the grammar, whole actions, their
synthesis, decoding and recognition, and the models directory format."""

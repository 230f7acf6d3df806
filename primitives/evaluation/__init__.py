"""How learning is measured: segmentation metrics against frame labels, discovery against the hidden
phases, synthesis against held-out demonstrations (Fig. 8)."""

from hoap_actions.primitives.evaluation.segmentation import (
    boundary_f1,
    edit_score,
    hungarian_frame_accuracy,
    hungarian_mapping,
    levenshtein,
    many_to_one_frame_accuracy,
    many_to_one_mapping,
    relabel,
)

__all__ = ["boundary_f1", "edit_score", "hungarian_frame_accuracy", "hungarian_mapping", "levenshtein",
           "many_to_one_frame_accuracy", "many_to_one_mapping", "relabel"]

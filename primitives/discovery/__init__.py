"""Unsupervised discovery of primitive classes from the effect on the object (eqs. 1-3, Figs. 4, 5, 7),
and the action grammar over those classes."""

from hoap_actions.primitives.discovery.estimator import (
    UNKNOWN,
    PrimitiveClass,
    PrimitiveDiscovery,
    Segment,
    effect_track,
)

__all__ = ["UNKNOWN", "PrimitiveClass", "PrimitiveDiscovery", "Segment", "effect_track"]

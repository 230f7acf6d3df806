"""Learning and recognising action primitives: HMM maths and PHMMs (``hmm``), discovery and the grammar
(``discovery``), action models (``models``), evaluation, and the command line's pipelines."""

from __future__ import annotations

import importlib

# the estimators a user reaches for first, imported on first use (each pulls in its own stage)
_ESTIMATORS = {
    "ParametricHMM": "hoap_actions.primitives.hmm.parametric_hmm",
    "PostureModel": "hoap_actions.primitives.hmm.posture",
    "PrimitiveDiscovery": "hoap_actions.primitives.discovery.estimator",
    "ActionGrammar": "hoap_actions.primitives.discovery.grammar",
    "ActionModels": "hoap_actions.primitives.models.action_models",
}
__all__ = sorted(_ESTIMATORS)


def __getattr__(name: str):
    if name in _ESTIMATORS:
        return getattr(importlib.import_module(_ESTIMATORS[name]), name)
    raise AttributeError(f"module 'hoap_actions.primitives' has no attribute {name!r}")

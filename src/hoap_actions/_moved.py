"""Import paths that moved when the code was grouped by pipeline stage: each still imports, warns once
and names its new path, so code written against an earlier layout keeps working."""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

MOVED: dict[str, str] = {
    "hoap_actions.cli": "hoap_actions.apps.cli",
    "hoap_actions.collect": "hoap_actions.apps.collect",
    "hoap_actions.controllers.execution": "hoap_actions.policies.execution",
    "hoap_actions.controllers.figures": "hoap_actions.policies.figures",
    "hoap_actions.controllers.grasp": "hoap_actions.policies.grasp",
    "hoap_actions.controllers.perception": "hoap_actions.vision.perception",
    "hoap_actions.controllers.phmm_paths": "hoap_actions.policies.phmm_paths",
    "hoap_actions.controllers.phmm_policy": "hoap_actions.policies.phmm_policy",
    "hoap_actions.controllers.policies": "hoap_actions.policies.registry",
    "hoap_actions.controllers.scripted_expert": "hoap_actions.policies.scripted_expert",
    "hoap_actions.default_models": "hoap_actions.models.shipped",
    "hoap_actions.envs.arm_ik": "hoap_actions.demonstration.arm_ik",
    "hoap_actions.envs.core": "hoap_actions.envs.hoap_env",
    "hoap_actions.envs.demo_scene": "hoap_actions.demonstration.scene",
    "hoap_actions.envs.demo_tasks": "hoap_actions.demonstration.tasks",
    "hoap_actions.envs.demonstrator": "hoap_actions.demonstration.demonstrator",
    "hoap_actions.envs.demonstrators": "hoap_actions.demonstration.bodies",
    "hoap_actions.envs.minimum_jerk": "hoap_actions.demonstration.minimum_jerk",
    "hoap_actions.envs.mocap": "hoap_actions.demonstration.mocap",
    "hoap_actions.envs.tasks.base": "hoap_actions.envs.task",
    "hoap_actions.envs.recording": "hoap_actions.demonstration.recording",
    "hoap_actions.episodes": "hoap_actions.apps.episodes",
    "hoap_actions.primitives.action_models": "hoap_actions.primitives.models.action_models",
    "hoap_actions.primitives.actions": "hoap_actions.primitives.models.whole_actions",
    "hoap_actions.primitives.connected_recognition": "hoap_actions.primitives.models.connected_recognition",
    "hoap_actions.primitives.datasets": "hoap_actions.demonstration.datasets",
    "hoap_actions.primitives.discovery_evaluation": "hoap_actions.primitives.evaluation.discovery",
    "hoap_actions.primitives.discovery_files": "hoap_actions.primitives.pipelines.discover",
    "hoap_actions.primitives.discovery_groups": "hoap_actions.primitives.discovery.groups",
    "hoap_actions.primitives.discovery_plots": "hoap_actions.primitives.discovery.plots",
    "hoap_actions.primitives.discovery_robustness": "hoap_actions.primitives.evaluation.discovery_robustness",
    "hoap_actions.primitives.effect_continuity": "hoap_actions.primitives.models.effect_continuity",
    "hoap_actions.primitives.effect_features": "hoap_actions.primitives.hmm.effect_features",
    "hoap_actions.primitives.gaussians": "hoap_actions.primitives.hmm.gaussians",
    "hoap_actions.primitives.grammar": "hoap_actions.primitives.discovery.grammar",
    "hoap_actions.primitives.grid_synthesis": "hoap_actions.primitives.evaluation.grid_synthesis",
    "hoap_actions.primitives.hmm_math": "hoap_actions.primitives.hmm.hmm_math",
    "hoap_actions.primitives.learning": "hoap_actions.primitives.pipelines.learn",
    "hoap_actions.primitives.mocap_cleaning": "hoap_actions.primitives.pipelines.mocap_cleaning",
    "hoap_actions.primitives.models_directory": "hoap_actions.primitives.models.models_directory",
    "hoap_actions.primitives.object_estimate": "hoap_actions.primitives.models.object_estimate",
    "hoap_actions.primitives.parametric_hmm": "hoap_actions.primitives.hmm.parametric_hmm",
    "hoap_actions.primitives.phmm_selection": "hoap_actions.primitives.hmm.selection",
    "hoap_actions.primitives.posture": "hoap_actions.primitives.hmm.posture",
    "hoap_actions.primitives.recognition_eval": "hoap_actions.primitives.pipelines.recognize",
    "hoap_actions.primitives.sparse_viterbi": "hoap_actions.primitives.hmm.sparse_viterbi",
    "hoap_actions.primitives.state_clustering": "hoap_actions.primitives.discovery.state_clustering",
    "hoap_actions.primitives.substrings": "hoap_actions.primitives.discovery.substrings",
    "hoap_actions.primitives.synthesis_eval": "hoap_actions.primitives.evaluation.synthesis",
    "hoap_actions.primitives.tracking": "hoap_actions.tracking",
    "hoap_actions.primitives.tracking.action_tracker": "hoap_actions.tracking.action_tracker",
    "hoap_actions.primitives.tracking.body_model": "hoap_actions.vision.body_model",
    "hoap_actions.primitives.tracking.edges": "hoap_actions.vision.edges",
    "hoap_actions.primitives.tracking.objects": "hoap_actions.vision.objects",
    "hoap_actions.primitives.tracking.silhouette": "hoap_actions.vision.silhouette",
}


class _MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Answers an old path with the module at its new one (the same module object, not a copy)."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec):
        return None

    def exec_module(self, module) -> None:
        old = module.__name__
        new = MOVED[old]
        warnings.warn(f"{old} moved to {new}; import it from there (the old path will be removed)",
                      FutureWarning, stacklevel=2)
        # the import system hands out whatever sys.modules holds under the old name once this returns
        sys.modules[old] = importlib.import_module(new)


def install() -> None:
    """Put the finder first, so an old name never loads a second copy of a module from a new folder."""
    if not any(isinstance(finder, _MovedModuleFinder) for finder in sys.meta_path):
        sys.meta_path.insert(0, _MovedModuleFinder())

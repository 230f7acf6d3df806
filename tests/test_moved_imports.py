"""Import paths of the earlier layout still work: the same module object, one warning naming the new path."""

from __future__ import annotations

import subprocess
import sys

import pytest

from hoap_actions._moved import MOVED

OLD_PUBLIC = {
    "hoap_actions.primitives.parametric_hmm": "ParametricHMM",
    "hoap_actions.default_models": "load_default_models",
    "hoap_actions.controllers.phmm_policy": "PHMMPolicy",
    "hoap_actions.primitives.tracking.action_tracker": "ActionTracker",
    "hoap_actions.cli": "main",
}


@pytest.mark.parametrize("old", sorted(OLD_PUBLIC))
def test_an_old_path_gives_the_new_module_and_says_where_it_went(old):
    """In a fresh interpreter, so that neither path is imported yet."""
    code = f"""
import importlib, warnings
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    old = importlib.import_module({old!r})
new = importlib.import_module({MOVED[old]!r})
assert old is new, (old, new)
assert getattr(old, {OLD_PUBLIC[old]!r}) is getattr(new, {OLD_PUBLIC[old]!r})
moved = [w for w in caught if issubclass(w.category, FutureWarning) and {MOVED[old]!r} in str(w.message)]
assert len(moved) == 1, [str(w.message) for w in caught]
"""
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]


def test_the_new_paths_import_without_a_warning():
    code = """
import importlib, warnings
warnings.simplefilter("error", FutureWarning)
for name in ("hoap_actions.primitives.hmm.parametric_hmm", "hoap_actions.models.shipped",
             "hoap_actions.policies.phmm_policy", "hoap_actions.tracking", "hoap_actions.apps.cli"):
    importlib.import_module(name)
"""
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]

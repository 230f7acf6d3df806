"""The package's shape: which module may import which (read from the source, not by importing it)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = {"core": "hoap_actions", "envs": "hoap_actions.envs", "controllers": "hoap_actions.controllers",
            "primitives": "hoap_actions.primitives"}


def _modules() -> dict[str, Path]:
    modules = {}
    for folder, package in PACKAGES.items():
        for path in sorted((ROOT / folder).rglob("*.py")):
            parts = path.relative_to(ROOT / folder).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            modules[".".join((package, *parts))] = path
    return modules


def _imports(path: Path, modules: dict[str, Path]) -> set[str]:
    """The package's modules that ``path`` imports (``from package import module`` counts the module)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names = [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
        found.update(name for name in names if name in modules)
    return found


MODULES = _modules()
GRAPH = {name: _imports(path, MODULES) - {name} for name, path in MODULES.items()}


def test_the_module_graph_is_found():
    assert "hoap_actions.envs.controls" in GRAPH
    assert "hoap_actions.controllers.hand_control" in GRAPH["hoap_actions.envs.controls"]


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of the directed graph as a list of nodes (first == last), or None (depth-first search)."""
    state: dict[str, int] = {}

    def visit(node: str, path: list[str]) -> list[str] | None:
        state[node] = 1
        for dep in sorted(graph.get(node, ())):
            if state.get(dep) == 1:
                return path[path.index(dep):] + [dep]
            if dep not in state and (cycle := visit(dep, path + [dep])):
                return cycle
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node, [node])):
            return cycle
    return None


def test_find_cycle_finds_a_known_cycle_and_no_other():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_no_module_imports_itself_back_through_others():
    """Package ``__init__`` files are left out: they only re-export."""
    graph = {m: {d for d in deps if MODULES[d].name != "__init__.py"} for m, deps in GRAPH.items()
             if MODULES[m].name != "__init__.py"}
    assert find_cycle(graph) is None


@pytest.mark.parametrize("module", ["hand_control", "retiming", "wholebody_ik"])
def test_the_control_layer_does_not_import_the_simulated_world(module):
    deps = GRAPH[f"hoap_actions.controllers.{module}"]
    assert not {d for d in deps if d.startswith("hoap_actions.envs")}, deps


def test_only_the_sim_facade_calls_pybullet():
    callers = [name for name, path in MODULES.items()
               if any(isinstance(n, (ast.Import, ast.ImportFrom)) and "pybullet" in
                      ([a.name for a in n.names] if isinstance(n, ast.Import) else [n.module or ""])
                      for n in ast.walk(ast.parse(path.read_text())))]
    assert callers == ["hoap_actions.envs.sim"], callers


def test_no_policy_reaches_into_the_envs_internals():
    """Policies ask the env through its public answers (parse_observation, capture, hand_status,
    robot_description), never through ``env.unwrapped``."""
    policies = [name for name in MODULES if name.startswith("hoap_actions.controllers.")]
    reaching = [name for name in policies if "unwrapped" in MODULES[name].read_text()]
    assert reaching == [], reaching


def test_every_subpackage_is_listed_for_the_wheel():
    """A folder with an ``__init__.py`` that ``pyproject.toml`` does not list is left out of the wheel,
    and its imports fail only after ``pip install`` (editable installs hide it)."""
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = set()
    for folder, package in PACKAGES.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            found.add(".".join((package, *init.parent.relative_to(ROOT / folder).parts)))
    assert found <= listed, f"not listed in pyproject.toml: {sorted(found - listed)}"

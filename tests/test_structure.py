"""The package's shape: which folder and module may import which (read from the source, not by importing it)."""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE_DIRS: dict[str, str] = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]

# The folders bottom to top: each may import only folders listed before it. Base utilities, control,
# the simulated world and its tasks, the demonstration world, learning (its own stages in order), vision,
# the tracker, the shipped models, policies, applications.
LAYERS = (
    "hoap_actions",
    "hoap_actions.urdf",
    "hoap_actions.controllers",
    "hoap_actions.envs",
    "hoap_actions.envs.tasks",
    "hoap_actions.demonstration",
    "hoap_actions.primitives",
    "hoap_actions.primitives.hmm",
    "hoap_actions.primitives.discovery",
    "hoap_actions.primitives.models",
    "hoap_actions.primitives.evaluation",
    "hoap_actions.primitives.baselines",
    "hoap_actions.primitives.pipelines",
    "hoap_actions.vision",
    "hoap_actions.tracking",
    "hoap_actions.imitation",
    "hoap_actions.models",
    "hoap_actions.policies",
    "hoap_actions.apps",
)
ENTRY_POINTS = ("__init__.py", "__main__.py")  # re-exports and ``python -m``: not part of the layering
MAX_MODULE_LINES = 600
MAX_FOLDER_MODULES = 15


def _modules() -> dict[str, Path]:
    modules = {}
    for package, folder in PACKAGE_DIRS.items():
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
    assert "hoap_actions.primitives.hmm.parametric_hmm" in GRAPH["hoap_actions.primitives.models.action_models"]


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
    policies = [name for name in MODULES if name.startswith(("hoap_actions.policies.", "hoap_actions.vision."))]
    reaching = [name for name in policies if "unwrapped" in MODULES[name].read_text()]
    assert reaching == [], reaching


def test_every_subpackage_is_listed_for_the_wheel():
    """A folder with an ``__init__.py`` that ``pyproject.toml`` does not list is left out of the wheel,
    and its imports fail only after ``pip install`` (editable installs hide it)."""
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {name for name, path in MODULES.items() if path.name == "__init__.py"}
    assert found == listed, f"listed but missing: {sorted(listed - found)}; not listed: {sorted(found - listed)}"


def _folder(module: str) -> str:
    return module if MODULES[module].name == "__init__.py" else module.rsplit(".", 1)[0]


def folder_edges() -> dict[tuple[str, str], tuple[str, str]]:
    """(importing folder, imported folder) -> one module import that makes the edge; entry points left out."""
    edges = {}
    for module, deps in GRAPH.items():
        if MODULES[module].name in ENTRY_POINTS:
            continue
        for dep in sorted(deps):
            if (a := _folder(module)) != (b := _folder(dep)):
                edges.setdefault((a, b), (module, dep))
    return edges


def test_every_folder_has_its_place_in_the_layers():
    folders = {_folder(name) for name in MODULES}
    assert folders == set(LAYERS), f"not placed: {sorted(folders - set(LAYERS))}; gone: {sorted(set(LAYERS) - folders)}"


def test_folders_import_only_the_layers_below_them():
    upward = {edge: why for edge, why in folder_edges().items() if LAYERS.index(edge[1]) >= LAYERS.index(edge[0])}
    assert upward == {}, upward


def test_the_folder_graph_has_no_cycle():
    graph: dict[str, set[str]] = {}
    for a, b in folder_edges():
        graph.setdefault(a, set()).add(b)
    assert find_cycle(graph) is None


def test_the_layer_check_sees_a_known_edge():
    assert ("hoap_actions.envs", "hoap_actions.controllers") in folder_edges()
    assert ("hoap_actions.policies", "hoap_actions.vision") in folder_edges()


def test_no_module_is_longer_than_the_limit():
    long = {name: n for name, path in MODULES.items() if (n := len(path.read_text().splitlines())) > MAX_MODULE_LINES}
    assert long == {}, long


def test_no_folder_holds_more_modules_than_the_limit():
    counts: dict[str, int] = {}
    for name, path in MODULES.items():
        if path.name not in ENTRY_POINTS:
            counts[_folder(name)] = counts.get(_folder(name), 0) + 1
    assert max(counts.values()) <= MAX_FOLDER_MODULES, counts


def test_every_old_import_path_points_to_a_module_that_exists():
    from hoap_actions._moved import MOVED

    assert set(MOVED.values()) <= set(MODULES), sorted(set(MOVED.values()) - set(MODULES))
    assert not set(MOVED) & set(MODULES), sorted(set(MOVED) & set(MODULES))

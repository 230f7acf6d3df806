"""The built wheel carries every asset: install it in a fresh venv and load every URDF and env from it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
import venv
import zipfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

CHECK_INSTALLED_COPY = """
import sys, pathlib
import gymnasium, hoap_actions
from hoap_actions.envs.sim import Sim
from hoap_actions.urdf import urdf_path
root = pathlib.Path(hoap_actions.__file__).resolve().parent
assert str(root).startswith(sys.prefix), f"imported {root}, not the wheel installed in {sys.prefix}"
urdfs = sorted(p.name for p in (root / "urdf").glob("*.urdf"))
sim = Sim()
for i, name in enumerate(urdfs):
    sim.load_urdf(f"body{i}", urdf_path(name), position=(3.0 * i, 10.0, 1.0))
sim.close()
for env_id in hoap_actions.ENV_IDS:
    env = gymnasium.make(env_id)
    env.reset(seed=0)
    env.step(env.action_space.sample())
    env.close()
print("URDFS", ",".join(urdfs))
"""


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    src = tmp_path_factory.mktemp("src")
    shutil.copytree(
        REPO,
        src / "repo",
        ignore=shutil.ignore_patterns(".git", ".venv", "build", "dist", "*.egg-info", "__pycache__", "results", "data"),
    )
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q", "-w", str(out),
         str(src / "repo")],
        check=True,
    )
    (whl,) = out.glob("hoap_actions-*.whl")
    return whl


def test_wheel_holds_only_the_hoap_actions_package(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    top_levels = {n.split("/")[0] for n in names}
    assert "hoap_actions" in top_levels
    assert all(t == "hoap_actions" or t.endswith(".dist-info") for t in top_levels), top_levels
    repo_urdfs = {p.name for p in (REPO / "urdf").glob("*.urdf")}
    assert repo_urdfs and {f"hoap_actions/urdf/{u}" for u in repo_urdfs} <= set(names)
    packages = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"]
    for package in packages:  # every folder the package maps, nested under hoap_actions/
        assert package.replace(".", "/") + "/__init__.py" in names, package
    shipped = {p.name for p in (REPO / "models" / "paper").iterdir()}
    assert shipped and {f"hoap_actions/models/paper/{n}" for n in shipped} <= set(names)  # the default models


def test_installed_wheel_loads_every_urdf_and_env(wheel, tmp_path):
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    python = env_dir / "bin" / "python"
    new_site = subprocess.run(
        [python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], capture_output=True, text=True
    ).stdout.strip()
    # The dependencies come from this interpreter's site-packages (with their own .pth files), added
    # after the new venv's own: no download, and hoap_actions itself comes from the wheel only.
    outer = sysconfig.get_paths()["purelib"]
    (Path(new_site) / "deps.pth").write_text(f"import site; site.addsitedir({outer!r})\n")
    subprocess.run([python, "-m", "pip", "install", "--no-deps", "--force-reinstall", "-q", str(wheel)], check=True)
    clean = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # only the wheel may provide hoap_actions
    result = subprocess.run(
        [python, "-c", CHECK_INSTALLED_COPY], cwd=tmp_path, capture_output=True, text=True, check=True, env=clean
    )
    shipped = result.stdout.split("URDFS ")[-1].strip().split(",")
    assert sorted(shipped) == sorted(p.name for p in (REPO / "urdf").glob("*.urdf"))

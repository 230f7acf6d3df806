"""Robot episodes as a Minari dataset: what offline-RL and imitation-learning code reads.

Minari (Farama's format for Gymnasium datasets) stores observations, actions, rewards, terminations,
truncations and the env's spec, so ``dataset.recover_environment()`` makes the env again. Episodes
are recorded through Minari's own ``DataCollector`` wrapper, one per seed ``seed .. seed + N - 1``; an
episode the policy ends early (it gave up, or is done) is stored as truncated. The dataset is claimed
before the first episode and appears only when complete (:func:`hoap_actions.outputs.claimed_directory`):
Minari writes it into a staging root, which then takes the dataset's place in one rename.

Minari is an optional extra: ``pip install "hoap-actions[minari]"``.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium

import hoap_actions  # noqa: F401  (registers the environments)
from hoap_actions.apps.episodes import run_episode
from hoap_actions.envs.robot import ROBOT_MODELS
from hoap_actions.errors import InvalidInputError
from hoap_actions.outputs import claimed_directory
from hoap_actions.seeds import check_seed

__all__ = ["collect"]


def _minari():
    try:
        import minari
    except ImportError:
        raise InvalidInputError('collecting datasets needs Minari: pip install "hoap-actions[minari]"') from None
    return minari


@contextlib.contextmanager
def _datasets_root(root: Path) -> Iterator[None]:
    """Minari writes under ``MINARI_DATASETS_PATH``: point it at ``root`` for the duration."""
    before = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(root)
    try:
        yield
    finally:
        if before is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = before


def collect(env_id: str, policy: str, episodes: int, seed: int, dataset_id: str,
            policy_kwargs: dict[str, Any] | None = None, overwrite: bool = False, robot: str = "full") -> Path:
    """Run the policy named ``policy`` (:data:`~hoap_actions.policies.registry.POLICIES`) for
    ``episodes`` episodes on ``env_id`` with the ``robot`` model (``"full"`` or ``"fixed_legs"``, kept in
    the dataset's env spec) and write them as the Minari dataset ``dataset_id`` (``namespace/name-v0``)
    in Minari's datasets folder; returns its path."""
    minari = _minari()
    from hoap_actions.policies.registry import policy_class

    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise InvalidInputError(f"episodes must be a positive integer; got {episodes!r}")
    check_seed(seed, count=episodes)
    if robot not in ROBOT_MODELS:
        raise InvalidInputError(f"robot={robot!r} is not a robot model; accepted: {list(ROBOT_MODELS)}")
    cls = policy_class(policy, env_id)
    try:
        namespace, name, version = minari.dataset.minari_dataset.parse_dataset_id(dataset_id)
    except Exception:  # Minari raises ValueError or AssertionError for a malformed id
        namespace = name = version = None
    if name is None or version is None:
        raise InvalidInputError(f"dataset_id {dataset_id!r} is not a Minari id; accepted: 'namespace/name-v0', e.g. "
                                f"'hoap_actions/PegInsert/{policy}-v0'")
    target = minari.storage.get_dataset_path(dataset_id)
    from minari.namespace import create_namespace, list_local_namespaces

    if namespace is not None and namespace not in list_local_namespaces():
        create_namespace(namespace)
    with claimed_directory(target, overwrite, what="dataset") as staging, _datasets_root(staging / "root"):
        env = minari.DataCollector(gymnasium.make(env_id, control_mode=cls.control_mode, robot=robot),
                                     record_infos=False)
        try:
            agent = cls(env, **(policy_kwargs or {}))
            for episode_seed in range(seed, seed + episodes):
                run_episode(env, agent, episode_seed)
            env.create_dataset(dataset_id, algorithm_name=f"hoap_actions {policy} policy",
                               description=f"{episodes} episodes of the {policy} policy on {env_id}, seeds "
                                           f"{seed}..{seed + episodes - 1} (hoap-actions collect)")
        finally:
            env.close()
        for part in (staging / "root" / dataset_id).iterdir():
            os.rename(part, staging / part.name)
        shutil.rmtree(staging / "root")  # the staging root's namespace records; the real one has its own
    return target

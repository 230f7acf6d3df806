"""The simulated world (PyBullet) and its Gymnasium environments.

Ids are namespaced ``hoap_actions/<Task>-v<N>`` (``Reach-v1``: targets drawn where the hand fits; v0 drew
some it cannot hold) and registered by :func:`register_envs`, which
``import hoap_actions`` calls.
"""

from __future__ import annotations

import gymnasium

# id -> entry point; the time limit is the task's episode_steps (30 Hz), which the fall penalty uses too
_SPECS: dict[str, str] = {
    "hoap_actions/PegInsert-v0": "hoap_actions.envs.tasks.peg_insert:PegInsertEnv",
    "hoap_actions/Reach-v1": "hoap_actions.envs.tasks.reach:ReachEnv",
    "hoap_actions/Imitate-v0": "hoap_actions.imitation.imitate_env:ImitateEnv",  # a string: no import edge upwards
}
_EPISODE_STEPS = {"hoap_actions/PegInsert-v0": 600, "hoap_actions/Reach-v1": 150, "hoap_actions/Imitate-v0": 600}
ENV_IDS: tuple[str, ...] = tuple(_SPECS)


def register_envs() -> None:
    """Register every hoap_actions environment id with Gymnasium (idempotent)."""
    for env_id, entry_point in _SPECS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=entry_point, max_episode_steps=_EPISODE_STEPS[env_id])

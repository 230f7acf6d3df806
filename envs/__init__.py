"""The simulated world (PyBullet) and its Gymnasium environments."""

from __future__ import annotations

import gymnasium

ENV_IDS: tuple[str, ...] = ()


def register_envs() -> None:
    """Register every hoap_actions environment id with Gymnasium (idempotent)."""
    for env_id in ENV_IDS:
        if env_id not in gymnasium.registry:
            pass

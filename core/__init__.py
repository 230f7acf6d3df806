"""hoap_actions: learn table-top manipulation primitives from demonstrations, then act and recognise.

Importing the package registers the Gymnasium environments listed in :data:`ENV_IDS`.
"""

from __future__ import annotations

from hoap_actions.envs import ENV_IDS, register_envs

__version__ = "0.1.0"
__all__ = ["ENV_IDS", "__version__", "register_envs"]

register_envs()

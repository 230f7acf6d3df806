"""hoap_actions: learn table-top manipulation primitives from demonstrations, then act and recognise.

Importing the package registers the Gymnasium environments listed in :data:`ENV_IDS`.
"""

from __future__ import annotations

import warnings

# placo imports hppfcl under its old name, which warns on every run of every command; the message is
# about placo's packaging, not about anything a user of this package can change.
warnings.filterwarnings("ignore", message="Please update your 'hppfcl' imports to 'coal'", category=DeprecationWarning)

from hoap_actions import _moved  # noqa: E402  (after the filter)
from hoap_actions.envs import ENV_IDS, register_envs  # noqa: E402  (after the filter)

_moved.install()

__version__ = "0.1.0"
__all__ = ["ENV_IDS", "__version__", "register_envs"]

register_envs()

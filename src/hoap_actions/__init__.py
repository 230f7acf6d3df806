"""hoap_actions: learn table-top manipulation primitives from demonstrations, then act and recognise.

Importing the package registers the Gymnasium environments listed in :data:`ENV_IDS`.
"""

from __future__ import annotations

import warnings

# placo imports hppfcl under its old name, which warns on every run of every command; the message is
# about placo's packaging, not about anything a user of this package can change.
warnings.filterwarnings("ignore", message="Please update your 'hppfcl' imports to 'coal'", category=DeprecationWarning)

from hoap_actions._startup import interrupts_end_the_start, is_command_line  # noqa: E402  (after the filter)

with interrupts_end_the_start(active=is_command_line()):  # the command line's first second goes here
    from hoap_actions import _moved
    from hoap_actions.envs import ENV_IDS, register_envs

    _moved.install()
    register_envs()

__version__ = "0.1.0"
__all__ = ["ENV_IDS", "__version__", "register_envs"]

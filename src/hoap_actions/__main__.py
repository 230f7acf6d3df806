"""``python -m hoap_actions`` and the ``hoap-actions`` command: the command line of :mod:`hoap_actions.apps.cli`."""

import signal
import sys

from hoap_actions._startup import EXIT_INTERRUPTED, interrupts_end_the_start

__all__ = ["run"]


def run() -> int:
    """The command line, with Ctrl-C or SIGTERM during its imports ending it as during its work (exit 130, one
    line, no traceback) instead of by the signal itself; the package's own imports are covered the same way
    (:mod:`hoap_actions._startup`). A signal the process was started ignoring stays ignored throughout."""
    with interrupts_end_the_start():
        from hoap_actions.apps.cli import main
    code = main()
    if code == EXIT_INTERRUPTED:  # interrupted and cleaned up: a further Ctrl-C while Python shuts down (its thread
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # joins) would end it by the signal, not with this exit status
    return code


if __name__ == "__main__":
    sys.exit(run())

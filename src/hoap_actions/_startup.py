"""Ctrl-C and SIGTERM while the command line starts: exit 130 with one line, as during its work, not a traceback."""

import contextlib
import os
import signal
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import NoReturn

EXIT_INTERRUPTED = 130  # as the command line exits on Ctrl-C once it runs
COMMAND = "hoap-actions"


def _interrupted_while_starting(signum: int, frame: object) -> NoReturn:
    """Exit at once: nothing is written before the command runs, and an exception raised here could surface inside
    an extension module's import as an unrelated import error."""
    print(f"{COMMAND}: interrupted while starting; nothing was written", file=sys.stderr, flush=True)
    os._exit(EXIT_INTERRUPTED)


def is_command_line() -> bool:
    """Whether this process is the command line starting (``hoap-actions``, or ``python -m`` while the module is
    being found: ``sys.argv[0]`` is ``"-m"`` then), not a program that imports the package."""
    first = sys.argv[0] if sys.argv else ""
    return first == "-m" or Path(first).name == COMMAND


@contextlib.contextmanager
def interrupts_end_the_start(active: bool = True) -> Iterator[None]:
    """While the block runs (imports), SIGINT and SIGTERM end the process with exit 130 and one line; the handlers
    before are restored after it. A signal the process was started ignoring stays ignored."""
    handlers = {} if not active else {
        sig: signal.signal(sig, _interrupted_while_starting) for sig in (signal.SIGINT, signal.SIGTERM)
        if signal.getsignal(sig) is not signal.SIG_IGN}
    try:
        yield
    finally:
        for sig, handler in handlers.items():
            signal.signal(sig, handler)

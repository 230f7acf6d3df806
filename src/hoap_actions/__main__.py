"""``python -m hoap_actions``: the same command line as ``hoap-actions``."""

import sys

from hoap_actions.apps.cli import main

if __name__ == "__main__":
    sys.exit(main())

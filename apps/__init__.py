"""Applications on top of the library: the ``hoap-actions`` command line, episode runs, Minari collection."""

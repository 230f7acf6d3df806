"""The pipelines behind ``hoap-actions discover``, ``learn`` and ``recognize``: recordings in, files out."""

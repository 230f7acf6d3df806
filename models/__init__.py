"""Action models shipped with the package, so that recognition (and later the robot and the tracker)
run on a fresh machine with no recording step. Each is a models directory
(:meth:`hoap_actions.primitives.models.action_models.ActionModels.save`) with a ``PROVENANCE.json`` saying
how :mod:`hoap_actions.models.shipped` built it."""

"""Using a trained model: :class:`~hcmt.inference.run.Run` (the handle: model, config, training-data facts;
:class:`~hcmt.inference.run.RunFolder` owns a run folder's files), the rollout loop, the paper's and the physics
metrics, evaluation and comparison of runs."""

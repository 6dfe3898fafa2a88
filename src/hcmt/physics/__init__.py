"""The physics of each dataset between the data and the models: the adapters (paper Table 9: inputs, outputs,
boundary conditions, the updater), trajectories with their hierarchy, and the frame pipeline (frame → graph, target,
loss mask) that training, rollout and attention maps share."""

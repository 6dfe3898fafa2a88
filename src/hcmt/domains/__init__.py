"""The per-dataset domains between the data and the models: each dataset's adapter (paper Table 9: inputs, outputs,
boundary conditions; Tables 8-9 from the configs; the config's model arguments), its trajectories and splits read
with their hierarchy, the frame pipeline (frame → graph, target, loss mask) that training, rollout and attention maps
share, and the updater (x^{t+1} from the model's output). The real physics, the finite-element solver, is
:mod:`hcmt.sim`."""

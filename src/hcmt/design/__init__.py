"""The design check an engineer runs: predictions of new Impact Plate designs (:mod:`~hcmt.design.predict`,
with ``--verify`` against the solver), sweeps of one parameter (:mod:`~hcmt.design.sweep`) and their pictures."""

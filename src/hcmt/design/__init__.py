"""The design check an engineer runs, split by job: its inputs (:mod:`~hcmt.design.inputs`: designs, names,
ranges, regions, confidence), the check (:mod:`~hcmt.design.check`: prediction, ``--verify`` against the solver,
the calls), its reports (:mod:`~hcmt.design.reports`: table, CSV, JSON, pictures); the response surface beside it
(:mod:`~hcmt.design.surrogate`), the read-outs of a trajectory (:mod:`~hcmt.design.readout`) and sweeps of one
parameter (:mod:`~hcmt.design.sweep`)."""

"""The design check an engineer runs, split by job: its inputs (:mod:`~hcmt.design.inputs`: designs, names,
ranges, regions, confidence), the check (:mod:`~hcmt.design.check`, the sequence; :mod:`~hcmt.design.prediction`,
the batched rollout; :mod:`~hcmt.design.calls`, the limit calls; :mod:`~hcmt.design.verification`, ``--verify``
against the solver; :mod:`~hcmt.design.notes`, the low-confidence notes), its records (:mod:`~hcmt.design.summary`:
a design's typed, frozen summary and its JSON), its reports (:mod:`~hcmt.design.reports`: table, CSV, JSON,
pictures); the response surface beside it (:mod:`~hcmt.design.surrogate`; its Gaussian process
:mod:`~hcmt.design.gp`, its file format :mod:`~hcmt.design.surrogate_file`, its training data
:mod:`~hcmt.design.surrogate_data`; beside a model's run, :mod:`~hcmt.design.surrogate_use`), the read-outs of
a trajectory (:mod:`~hcmt.design.readout`) and sweeps of one parameter (:mod:`~hcmt.design.sweep`)."""

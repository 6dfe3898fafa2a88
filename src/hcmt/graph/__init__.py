"""Graphs of HCMT (paper, "Encoder" and "Pooling Method").

* :mod:`~hcmt.graph.edges` -- mesh edges from cells; mesh and contact edge features;
* :mod:`~hcmt.graph.contact` -- objects (cell-graph components) and contact edges (KD-tree or dense torch);
* :mod:`~hcmt.graph.pooling` -- bi-stride node pooling;
* :mod:`~hcmt.graph.remesh` -- Delaunay remeshing of a pooled level, the 2-hop (no-remesh) alternative;
* :mod:`~hcmt.graph.quality` -- scaled Jacobian and angles;
* :mod:`~hcmt.graph.hierarchy` -- :class:`Hierarchy`, ``build_hierarchy``, its cache, ``pool``/``unpool``;
* :mod:`~hcmt.graph.build` -- ``frame_graph``: one frame -> :class:`~hcmt.graph.batch.Graph`;
* :mod:`~hcmt.graph.batch` -- the model-input contract (``Graph``, ``collate``);
* :mod:`~hcmt.graph.report` -- the ``hcmt hierarchy`` command.
"""

"""Pictures and ParaView export of rollouts (``hcmt plot``, ``hcmt export``); matplotlib without a display.

* :mod:`~hcmt.viz.rollouts`: one trajectory's ground truth beside the runs' rollouts (rolled out when missing);
* :mod:`~hcmt.viz.meshplot`: drawing a nodal field on a deformed mesh, the zoom window around the impact;
* :mod:`~hcmt.viz.contours`: stress contours, ground truth beside predictions (paper Fig. 5, 11-14);
* :mod:`~hcmt.viz.animation`: a GIF of the rollouts beside the ground truth;
* :mod:`~hcmt.viz.curves`: RMSE per rollout step, training curves;
* :mod:`~hcmt.viz.hierarchy`: level-wise meshes (Fig. 4), before/after remeshing (Fig. 10);
* :mod:`~hcmt.viz.attention`: CMT/HMT attention maps as sparse matrices (Fig. 6, 15-18);
* :mod:`~hcmt.viz.export`: VTU (+ .pvd) or XDMF time series through meshio;
* :mod:`~hcmt.cli.viz`: the two commands.

matplotlib (and meshio, for the export) come with the ``viz`` extra (``pip install 'hcmt[viz]'``); without
matplotlib, importing this package fails in one line naming it.
"""

from hcmt.errors import require_installed

require_installed("viz", "matplotlib")

"""The map: PointFusion with concept vectors, queries, regions, persistence.

* :mod:`~conceptfusion.map.fusion` - :class:`PointFusionMap`, projective association and
  confidence-weighted running means (eqs. 1-2), compiled loops in ``_kernels``;
* :mod:`~conceptfusion.map.feature_store` - per-point concept vectors as mixtures of a shared bank;
* :mod:`~conceptfusion.map.dense` - dense (H, W, d) features grouped exactly into a palette;
* :mod:`~conceptfusion.map.quantize` - a bounded palette for per-pixel features with no repeats;
* :mod:`~conceptfusion.map.query` - scores, relative thresholds, relevancy, ``locate``;
* :mod:`~conceptfusion.map.regions` - connected 3D regions a query selected;
* :mod:`~conceptfusion.map.thin` - a map thinned to a point budget on a voxel grid;
* :mod:`~conceptfusion.map.persistence` - versioned atomic ``.npz`` files and PLY export.

May import: :mod:`conceptfusion` base modules and :mod:`conceptfusion.perception`'s data types.
"""

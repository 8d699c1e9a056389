"""ConceptFusion, the mapping core: simulator-agnostic, agent-agnostic.

* :mod:`conceptfusion.map` - the PointFusion map with concept vectors (paper eqs. 1-2), its
  compact feature store, queries and 3D regions, saving and loading;
* :mod:`conceptfusion.perception` - encoders, mask proposers, pixel-aligned features (eqs. 3-6)
  and the frame featurizers (perceived or privileged oracle) that feed a map;
* :mod:`conceptfusion.spatial` - the 3D spatial comparators between map regions;
* :mod:`conceptfusion.mapper` - the concept mapper (frames in, answers to text queries out) and
  :func:`~conceptfusion.mapper.make_mapper`, which builds one with the calibrated score floor on;
  :mod:`conceptfusion.frame_folders` reads a folder of a user's posed RGB-D frames (``cfharness map``);
* base modules the other packages may share: :mod:`conceptfusion.frames` (the one RGB-D frame
  type), :mod:`conceptfusion.cameras` (pinhole math, OpenCV convention),
  :mod:`conceptfusion.errors` (the project's error hierarchy), :mod:`conceptfusion.names`
  (nearest-name lookups), :mod:`conceptfusion.io_utils` (atomic writes);
  :mod:`conceptfusion.synthetic` renders exact box scenes for tests and the simulator-free demo.

The few names a user needs are importable from here (loaded on first use, so ``import
conceptfusion`` stays cheap: no torch, no simulator)::

    from conceptfusion import RGBDFrame, load_map, make_encoder, make_mapper, register_encoder, save_map

May import: nothing of this project outside ``conceptfusion`` (no simulator, agent, planner or
harness module); heavy optional libraries (torch, transformers) only where they are used.
"""

from __future__ import annotations

from conceptfusion.names import lazy_exports

__all__ = ["RGBDFrame", "load_map", "make_encoder", "make_mapper", "register_encoder", "save_map"]


__getattr__, __dir__ = lazy_exports(__name__, {
    "register_encoder": "conceptfusion.perception.registry", "make_encoder": "conceptfusion.perception.registry",
    "load_map": "conceptfusion.map.persistence", "save_map": "conceptfusion.map.persistence",
    "RGBDFrame": "conceptfusion.frames", "make_mapper": "conceptfusion.mapper",
})
"""Each public name of :data:`__all__` is imported from its module on first use."""

"""Perception: from an RGB-D frame to pixel-aligned concept features.

* encoders (:mod:`~.encoders` protocol, :mod:`~.registry` by spec string with user encoders
  registered there behind :mod:`~.checked`'s output checks, the offline MiniLM
  :mod:`~.text_tower`, the shipped embedded :mod:`~.image_tower`, CLIP via :mod:`~.clip_hf` and
  :mod:`~.clip_onnx`, :mod:`~.audio` and :mod:`~.speech` for spoken queries);
* :mod:`~.masks` - class-agnostic mask proposers (RGB-D graph segmentation, optional SAM);
* :mod:`~.features` and :mod:`~.pipeline` - the paper's eqs. 3-6, palette form;
* :mod:`~.oracle` - privileged features from ground-truth segmentation;
* :mod:`~.featurizer` - the one perception object a map is built with (perceived or oracle): its
  factory, with the parts by job in :mod:`~.spec` (names), :mod:`~.score_floor` (score floors),
  :mod:`~.featurizer_base` (the protocol), :mod:`~.perceived` and :mod:`~.oracle_featurizers`.

May import: :mod:`conceptfusion` base modules; nothing of the simulator, agents or harness.
"""

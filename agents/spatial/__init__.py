"""Spatial questions in words to 3D comparator calls: the offline pattern grammar, the
meaning-based parser (grammar fast path, noun-phrase chunks and MiniLM relation classes:
``semantic.py``, ``lexicon.py``, exemplars in ``relations.json``), the OpenAI-compatible chat
backend, the parser registry, the call signature they all produce (with a confidence) and the
calibration of the semantic parser's refusal threshold.

May import: :mod:`conceptfusion` (the comparators) and base modules.
"""

"""Spatial questions in words to 3D comparator calls: the offline pattern grammar, the
OpenAI-compatible chat backend, the parser registry and the call signature they both produce.

May import: :mod:`conceptfusion` (the comparators) and base modules.
"""

"""3D spatial comparators between map regions (howFar, isToTheLeft/Right, onTopOf,
under, isBigger, canFitInside, isContained) and the robust box geometry they share.

May import: :mod:`conceptfusion.map` (regions) and base modules.
"""

"""Object and furniture assets: procedural objects from MuJoCo primitives (``objects``),
meshes from ``pybullet_data`` (``meshes``), optional LIBERO assets (``libero``) and procedural
furniture with its support surfaces (``furniture``), and the object library (``library``: 91
categories, 606 instances, scene assets ``"lib:<id>"``).

May import: :mod:`conceptfusion` base modules.
"""

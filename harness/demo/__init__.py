"""The quick mapping demo (``cfharness demo``): fuse rendered frames into a map, query it,
score the answers (a MuJoCo tabletop with the embedded encoder, ``tabletop``, or the exact box
scene, ``run``; their settings and scoring in ``scoring``).

May import: :mod:`agents`, :mod:`sim_envs`, :mod:`conceptfusion`.
"""

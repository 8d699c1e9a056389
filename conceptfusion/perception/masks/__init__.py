"""Class-agnostic mask proposers: protocol and checks (``base``), the RGB-D graph
segmentation proposer (``rgbd`` with ``regions``, settings in ``rgbd_config``), optional SAM (``sam``), and the registry
that builds one from a spec string (``registry``).

May import: :mod:`conceptfusion` base modules and :mod:`conceptfusion.perception`.
"""

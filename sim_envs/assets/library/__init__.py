"""The object library: a long tail of object categories and instances for both simulators.

- :mod:`.taxonomy`: :class:`Category` (name, synonyms, parents, materials, colours, size range,
  functions, shape variants, source, licence), :class:`Group` (inner nodes: ``mug ->
  drinkware -> container -> object``), :data:`LICENCES`, validation.
- :mod:`.catalogue_kitchen`, :mod:`.catalogue_home`: the groups and categories (data).
- :mod:`.geometry`, :mod:`.shapes_round`, :mod:`.shapes_built`, :mod:`.shapes`: procedural meshes
  with texture coordinates (revolved profiles, boxes, slabs, tube arcs) and the registry of
  shape variants.
- :mod:`.named`: the named meshes of ``pybullet_data`` as instances (reusing
  :mod:`sim_envs.assets.meshes`).
- :mod:`.catalogue`: :class:`Instance` and the catalogue, drawn deterministically from hashes
  (:func:`catalogue_hash` pins it); scene assets ``"lib:<instance id>"``.
- :mod:`.palette`, :mod:`.textures`: colours, materials and their procedural PNG textures.
- :mod:`.export`: cached normalised OBJ + convex collision pieces + texture per instance.
- :mod:`.mjcf` (MuJoCo) and :mod:`.urdf` (PyBullet): loading.
- :mod:`.check` (``python -m sim_envs.assets.library.check``) and :mod:`.contact_sheet`: scripts.

Textures are small PNG images with texture coordinates on the meshes, not MuJoCo builtin
textures: PyBullet has no builtin textures, and the same image through the same UVs makes an
instance look the same in both simulators; an image also carries material patterns (wood grain,
weave, brushed metal) that two-colour builtins cannot. Glass renders opaque and tinted (depth
cameras and the segmentation pass would mishandle transparency). One material per instance.

LIBERO objects are not in the library: the asset packages are an optional extra that is not
installed here, their TurboSquid models may not be used for shipped weights, and which of the
remaining ones (Google Scanned Objects, CC-BY 4.0; HOPE) ship complete was not verified.

May import: :mod:`sim_envs.assets` and :mod:`conceptfusion` base modules.
"""

from sim_envs.assets.library.catalogue import (
    LIB_PREFIX, Catalogue, Instance, build_catalogue, catalogue, catalogue_hash, get_category, get_instance,
    instance_of_asset, is_library_asset, scene_instance,
)
from sim_envs.assets.library.export import ExportedInstance, export_instance, instance_size
from sim_envs.assets.library.mjcf import library_asset_xml, library_geoms
from sim_envs.assets.library.palette import MATERIALS, PALETTE
from sim_envs.assets.library.taxonomy import LICENCES, Category, Group, Licence
from sim_envs.assets.library.urdf import instance_urdf, load_instance

__all__ = [
    "LIB_PREFIX", "Catalogue", "Instance", "Category", "Group", "Licence", "LICENCES", "MATERIALS", "PALETTE",
    "build_catalogue", "catalogue", "catalogue_hash", "get_category", "get_instance", "instance_of_asset",
    "is_library_asset", "scene_instance", "ExportedInstance", "export_instance", "instance_size",
    "library_asset_xml", "library_geoms", "instance_urdf", "load_instance",
]

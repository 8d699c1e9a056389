"""The named meshes of ``pybullet_data`` as library instances.

The seven kinds of :data:`sim_envs.assets.meshes.MESH_KINDS` (duck, teddy bear, soccer ball,
lego brick, jenga block, mug, tray) plus the other named objects ``pybullet_data`` ships that
are usable as household objects: a domino, the three toy shapes and the shape sorter of
``toys/``, and the textured torus (a toy ring). Left out: ``bunny.obj`` (the Stanford bunny;
its terms ask for research use, so not for shipped weights), ``stone.obj``, ``table/``,
``cube.obj`` and the spheres (plain primitives, not named things), ``random_urdfs/`` (random
shapes with no names), robots, terrain and scenery.

Painted meshes (no texture of their own) give one instance per colour in :data:`NAMED`; textured
ones one instance in their own texture. Normalising and caching is :mod:`sim_envs.assets.meshes`.
"""

from __future__ import annotations

from dataclasses import dataclass

from sim_envs.assets.meshes import MESH_KINDS, MeshKind

__all__ = ["NamedMesh", "NAMED", "EXTRA_MESH_KINDS"]

EXTRA_MESH_KINDS: dict[str, MeshKind] = {
    "domino": MeshKind("domino", ("a domino",), (0.025, 0.006, 0.051), "domino/domino.obj", "domino/domino.jpg", "z", "black"),
    "toy_cube": MeshKind("toy block", ("a toy cube",), (0.087, 0.087, 0.065), "toys/cube.obj", None, "z"),
    "toy_cylinder": MeshKind("toy block", ("a toy cylinder",), (0.077, 0.116, 0.058), "toys/cylinder.obj", None, "z"),
    "toy_prism": MeshKind("toy block", ("a toy prism",), (0.084, 0.064, 0.118), "toys/prism.obj", None, "z"),
    "shape_sorter": MeshKind("shape sorter", ("a shape sorter",), (0.4, 0.4, 0.4), "toys/shape_sorter.obj", None, "z"),
    "torus": MeshKind("toy ring", ("a ring",), (1.5, 1.5, 0.495), "torus/torus_textured.obj", None, "y"),
}
"""Named ``pybullet_data`` meshes beyond ``MESH_KINDS`` (default sizes: the file's own units)."""


@dataclass(frozen=True)
class NamedMesh:
    """How one named mesh enters the library."""

    kind: str
    """Key of ``MESH_KINDS`` or :data:`EXTRA_MESH_KINDS`."""
    category: str
    """Library category name."""
    material: str
    """Material it looks made of."""
    colors: tuple[str, ...]
    """Its colour (textured meshes) or the colours it is painted in, one instance each."""
    scale: float
    """Longest side of the instance (metres)."""
    licence: str
    """Licence id (``taxonomy.LICENCES``)."""

    @property
    def mesh_kind(self) -> MeshKind:
        """The :class:`MeshKind` of :attr:`kind`."""
        return MESH_KINDS[self.kind] if self.kind in MESH_KINDS else EXTRA_MESH_KINDS[self.kind]


NAMED: tuple[NamedMesh, ...] = (
    NamedMesh("duck", "rubber duck", "rubber", ("yellow",), 0.099, "SCEA-1.0"),
    NamedMesh("teddy", "teddy bear", "fabric", ("brown", "tan", "beige"), 0.093, "zlib"),
    NamedMesh("soccer_ball", "soccer ball", "rubber", ("white",), 0.12, "zlib"),
    NamedMesh("lego", "lego brick", "plastic", ("red", "blue", "yellow"), 0.064, "zlib"),
    NamedMesh("jenga", "jenga block", "wood", ("orange",), 0.15, "zlib"),
    NamedMesh("mesh_mug", "mug", "ceramic", ("white", "red", "blue"), 0.122, "zlib"),
    NamedMesh("tray", "tray", "plastic", ("white",), 0.30, "zlib"),
    NamedMesh("domino", "domino", "plastic", ("black",), 0.051, "zlib"),
    NamedMesh("toy_cube", "building blocks", "wood", ("red", "green"), 0.087, "zlib"),
    NamedMesh("toy_cylinder", "building blocks", "wood", ("blue", "yellow"), 0.116, "zlib"),
    NamedMesh("toy_prism", "building blocks", "wood", ("green", "orange"), 0.118, "zlib"),
    NamedMesh("shape_sorter", "shape sorter", "plastic", ("red", "blue"), 0.16, "zlib"),
    NamedMesh("torus", "toy ring", "plastic", ("red", "green", "blue"), 0.12, "zlib"),
)
"""Every named mesh of the library."""

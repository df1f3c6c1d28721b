"""The assets a converted USD stage names, copied flat beside it (or gathered into the
``.usdz`` package) under safe, unique names; arcs usd-core could not compose, copied and
authored again on the flattened layer."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from pxr import Ar, Sdf

from ..atomic import atomic_path
from ..convert.output_folder import free_name
from ..errors import FormatError
from ..scene import Scene, safe_name
from .usd_assets import KeptArc, asset_bytes
from .usd_mtlx import mtlx_copy


class AssetFiles:
    """Assets the output names: copied flat into out_dir (or gathered for a package)
    under safe, unique names."""

    def __init__(self, out_dir: Path, reserved: set[str], package: bool, others: dict | None = None, links=None):
        self.out_dir, self.taken, self.package = out_dir, set(reserved), package
        self.links = None if package else links  # csm_assets.convert.links.Links: assets named where they are
        self.others = {} if package else dict(others or {})  # other scenes' files beside a package: not ours
        self.by_source: dict[str, str] = {}
        self.written: list[Path] = []
        self.packed: dict[str, Path] = {}
        self._tmp = tempfile.TemporaryDirectory() if package else None

    def name_for(self, resolved: str, authored: str, data: bytes | None = None,
                 name: str | None = None) -> str | None:
        """The flat name of the copy of ``resolved`` (copied on first use, under ``name``
        if given; ``data``: bytes to write instead of the file's own); None when it cannot
        be read."""
        if resolved in self.by_source:
            return self.by_source[resolved]
        if data is None and Ar.IsPackageRelativePath(resolved):
            data = asset_bytes(resolved)
            if data is None:
                return None
        name = name or self.free_name(authored, data if data is not None else Path(resolved))
        if data is not None:
            self.add_bytes(name, data)
        else:
            self.add_file(name, Path(resolved))
        self.taken.add(name)
        self.by_source[resolved] = name
        return name

    def asset_path(self, resolved: str, authored: str) -> str | None:
        """The asset path the output names ``resolved`` by: a relative path to the file where it
        is when :attr:`links` can name it, else ``./`` its flat copy (:meth:`name_for`); None
        when it cannot be read."""
        link = self.links.to(resolved) if self.links is not None and not Ar.IsPackageRelativePath(resolved) else None
        if link is not None:
            return link if link.startswith("../") else f"./{link}"
        name = self.name_for(resolved, authored)
        return None if name is None else f"./{name}"

    def udim_asset_path(self, authored: str, tiles: dict[int, str]) -> str:
        """The asset path of a UDIM set: ``dir/name.<UDIM>.ext`` where the tiles are, when
        :attr:`links` names every tile in one folder under the authored pattern's name, else
        ``./`` its copied pattern (:meth:`udim_pattern`)."""
        found = {t: self.links.to(f) for t, f in tiles.items()} if self.links is not None else {}
        name = Path(authored.replace("\\", "/")).name
        heads = {link.rsplit("/", 1)[0] for link in found.values() if link and "/" in link}
        if found and len(heads) == 1 and all(link == f"{next(iter(heads))}/{name.replace('<UDIM>', str(t))}"
                                             for t, link in found.items()):
            pattern = f"{next(iter(heads))}/{name}"
            return pattern if pattern.startswith("../") else f"./{pattern}"
        return f"./{self.udim_pattern(authored, tiles)}"

    def udim_pattern(self, authored: str, tiles: dict[int, str]) -> str:
        """A free ``base.<UDIM>.ext`` pattern with every tile of ``tiles`` copied under it."""
        key = "udim:" + "|".join(tiles.values())
        if key in self.by_source:
            return self.by_source[key]
        head, tail = Path(authored).name.split("<UDIM>", 1)
        ext = "." + safe_name(tail.rsplit(".", 1)[1]).lower() if "." in tail else ""
        base = safe_name(head) if head.strip("._") else "udim"
        held = self.taken | set(self.others)
        stem = free_name(base, "", lambda s: any(f"{s}.{tile}{ext}" in held for tile in tiles))
        names = {tile: f"{stem}.{tile}{ext}" for tile in tiles}
        for tile, resolved in tiles.items():
            self.name_for(resolved, names[tile], name=names[tile])
        self.by_source[key] = f"{stem}.<UDIM>{ext}"
        return self.by_source[key]

    def free_name(self, authored: str, content=None) -> str:
        """A flat, safe name for a copy of ``authored`` holding ``content`` (a path or bytes)."""
        return free_name(safe_name(Path(authored).stem), Path(authored).suffix.lower(), self.taken, self.others,
                         content)

    def add_file(self, name: str, src: Path) -> None:
        if self.package:
            self.packed[name] = Path(src)
            return
        with atomic_path(self.out_dir / name) as tmp:
            shutil.copyfile(src, tmp)
        self.written.append(self.out_dir / name)

    def add_bytes(self, name: str, data: bytes) -> None:
        if self.package:
            file = Path(self._tmp.name) / name
            file.write_bytes(data)
            self.packed[name] = file
            return
        with atomic_path(self.out_dir / name) as tmp:
            tmp.write_bytes(data)
        self.written.append(self.out_dir / name)


def keep_arc(scene: Scene, flat: Sdf.Layer, arc: KeptArc, files: AssetFiles) -> None:
    """Copy the file of an arc usd-core could not compose and author the arc again on the
    flattened layer, pointing at the copy (MaterialX documents: see :mod:`.usd_mtlx`)."""
    mtlx = arc.resolved.lower().endswith(".mtlx")
    data = mtlx_copy(scene, arc.resolved, arc.files, files.name_for) if mtlx else None
    name = files.name_for(arc.resolved, arc.authored, data)
    if name is None:
        raise FormatError(scene.path, f"{arc.kind} {arc.authored!r} cannot be read to be copied")
    asset = f"./{name}"
    if arc.kind == "subLayer":
        flat.subLayerPaths.append(asset)
        flat.subLayerOffsets[len(flat.subLayerPaths) - 1] = arc.offset
        return
    spec = flat.GetPrimAtPath(arc.site) or Sdf.CreatePrimInLayer(flat, arc.site)
    if arc.kind == "reference":
        spec.referenceList.Prepend(Sdf.Reference(asset, arc.prim_path, arc.offset))
    else:
        spec.payloadList.Prepend(Sdf.Payload(asset, arc.prim_path, arc.offset))

"""The assets a converted USD stage names, copied flat beside it (or gathered into the
``.usdz`` package) under safe, unique names; arcs usd-core could not compose, copied and
authored again on the flattened layer."""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

from pxr import Ar, Sdf

from ..atomic import atomic_path
from ..errors import FormatError
from ..scene import Scene, safe_name
from .usd_assets import KeptArc, asset_bytes
from .usd_mtlx import mtlx_copy


class AssetFiles:
    """Assets the output names: copied flat into out_dir (or gathered for a package)
    under safe, unique names."""

    def __init__(self, out_dir: Path, reserved: set[str], package: bool):
        self.out_dir, self.taken, self.package = out_dir, set(reserved), package
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
        name = name or self.free_name(authored)
        if data is None and Ar.IsPackageRelativePath(resolved):
            data = asset_bytes(resolved)
            if data is None:
                return None
        if data is not None:
            self.add_bytes(name, data)
        else:
            self.add_file(name, Path(resolved))
        self.taken.add(name)
        self.by_source[resolved] = name
        return name

    def udim_pattern(self, authored: str, tiles: dict[int, str]) -> str:
        """A free ``base.<UDIM>.ext`` pattern with every tile of ``tiles`` copied under it."""
        key = "udim:" + "|".join(tiles.values())
        if key in self.by_source:
            return self.by_source[key]
        head, tail = Path(authored).name.split("<UDIM>", 1)
        ext = "." + safe_name(tail.rsplit(".", 1)[1]).lower() if "." in tail else ""
        base, n = safe_name(head) if head.strip("._") else "udim", 0
        while True:
            stem = f"{base}_{n}" if n else base
            names = {tile: f"{stem}.{tile}{ext}" for tile in tiles}
            if not self.taken.intersection(names.values()):
                break
            n += 1
        for tile, resolved in tiles.items():
            self.name_for(resolved, names[tile], name=names[tile])
        self.by_source[key] = f"{stem}.<UDIM>{ext}"
        return self.by_source[key]

    def free_name(self, authored: str) -> str:
        suffix = Path(authored).suffix.lower()
        stem = safe_name(Path(authored).stem)
        name, n = f"{stem}{suffix}", 1
        while name in self.taken:
            name, n = f"{stem}_{n}{suffix}", n + 1
        return name

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

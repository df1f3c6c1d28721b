"""What a USD scene pulls in: its layers (sublayers, references, payloads) and the assets
its attributes name, checked against the project root before anything is composed.

:func:`open_stage` walks the layer graph with Sdf first, so no layer outside the
project root is ever read: every arc's asset path obeys the policy of textures (absolute
paths and URLs refused; ``../`` outside the project root refused unless allowed). A
missing or unreadable layer is refused too (a flattened output would silently lack it).
An arc to a file usd-core has no reader for (a MaterialX ``.mtlx`` without the MaterialX
plugin, an Alembic file) is kept (:class:`KeptArc`) on each prim where it lands: its own
site in the root layer stack, else where composing reports it failed. The writer copies
the file and authors the arc again there on the flattened output.
"""

from __future__ import annotations

import dataclasses
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from pxr import Ar, Sdf, Usd

from .. import references
from ..errors import FormatError, not_regular
from .usd_messages import usd_diagnostics, usd_reason

ARC_KINDS = ("subLayer", "reference", "payload")


@dataclass
class KeptArc:
    """An arc usd-core cannot compose, kept as authored: ``kind`` (one of ARC_KINDS),
    ``site`` (the prim it is authored on; ``/`` for a sublayer), the ``authored`` asset
    path and the ``resolved`` file, the target ``prim_path`` and ``offset``."""

    kind: str
    site: Sdf.Path
    authored: str
    resolved: str
    prim_path: Sdf.Path = field(default_factory=Sdf.Path)
    offset: Sdf.LayerOffset = field(default_factory=Sdf.LayerOffset)
    files: dict[str, str] = field(default_factory=dict)  # what a MaterialX document names
    bound: list = field(default_factory=list)  # material paths meshes are bound to through it (unresolved)


@dataclass
class UsdSource:
    """``Scene.source`` of a USD scene: the composed stage and the arcs it could not compose."""

    stage: Usd.Stage
    kept: list[KeptArc] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)  # arcs of unselected variants to no file: their appearing counts


def refuse_asset(scene_path: Path, authored: str, resolved: str, within: Path | None, what: str = "") -> None:
    """FormatError naming the scene unless the asset ``authored`` (resolving to
    ``resolved``) is relative and inside ``within`` (the project root, see
    :func:`csm_assets.references.reach`; None: anywhere)."""
    references.check(scene_path, authored, what)
    if resolved and not Ar.IsPackageRelativePath(resolved):
        references.refuse_outside(scene_path, authored, resolved, within, what)


def _arcs(layer: Sdf.Layer):
    """``(kind, site, authored, prim_path, offset)`` of every external arc of ``layer``."""
    for path, offset in zip(layer.subLayerPaths, layer.subLayerOffsets):
        yield "subLayer", Sdf.Path.absoluteRootPath, path, Sdf.Path(), offset
    if not layer.GetCompositionAssetDependencies():
        return
    sites = []
    layer.Traverse(Sdf.Path.absoluteRootPath,
                   lambda p: sites.append(p) if p.IsPrimPath() or p.IsPrimVariantSelectionPath() else None)
    for site in sites:
        spec = layer.GetPrimAtPath(site)
        if spec is None:
            continue
        for kind, items in (("reference", spec.referenceList), ("payload", spec.payloadList)):
            for item in [*items.explicitItems, *items.prependedItems, *items.appendedItems, *items.addedItems]:
                if item.assetPath:
                    yield kind, site, item.assetPath, item.primPath, item.layerOffset


def _open_layer(scene_path: Path, identifier: str, what: str) -> Sdf.Layer:
    messages: list[str] = []
    try:
        with usd_diagnostics(messages):
            layer = Sdf.Layer.FindOrOpen(identifier)
    except Exception as e:  # pxr raises Tf.ErrorException, a plain Exception subclass
        messages.append(str(e))
        layer = None
    if layer is None:
        why = usd_reason(messages[-1]) if messages else ""
        raise FormatError(scene_path, f"{what}is not a readable USD layer" + (f": {why}" if why else ""))
    return layer


def walk_layers(scene_path: Path, within: Path | None):
    """Check every layer the scene composes, before composing it (see the module's text):
    the arcs to keep, the layers opened (held open, so composing does not read them
    again) and ``(asset, refusal)`` of arcs inside variants that are refused only if
    composing opens them. Raises FormatError naming the scene and the asset."""
    root = _open_layer(scene_path, str(scene_path), "")
    todo, seen, kept, layers, deferred = [(root, True)], {root.identifier}, [], [root], []
    while todo:
        layer, root_stack = todo.pop()
        for kind, site, authored, prim_path, offset in _arcs(layer):
            where = f"{kind} {authored!r} of {layer.GetDisplayName()} at <{site}>: "
            if "`" in authored:
                raise FormatError(scene_path, f"{where}expression asset paths are not supported")
            anchored = Sdf.ComputeAssetPathRelativeToLayer(layer, authored)
            refuse_asset(scene_path, authored, anchored, within, f"the {kind} ")
            resolved = str(Ar.GetResolver().Resolve(anchored))
            problem = None
            ext = Ar.GetResolver().GetExtension(resolved or anchored)
            if not resolved:
                problem = "the file does not exist; refused (the output would silently lack what it holds)"
            elif Sdf.FileFormat.FindByExtension(ext) is None:
                arc = KeptArc(kind, site, authored, resolved, prim_path, offset)
                if root_stack and not site.ContainsPrimVariantSelection():
                    kept.append(arc)  # its stage path is its site
                else:  # kept where composing says it lands (see open_stage)
                    deferred.append((resolved, where + f"usd-core cannot read .{ext} files (no plugin), and "
                                     f"where the arc lands could not be told; refused", (arc, layer.realPath)))
                continue
            if problem and site.ContainsPrimVariantSelection():
                deferred.append((anchored, where + problem, None))  # refused only if that variant is selected
                continue
            if problem:
                raise FormatError(scene_path, where + problem)
            if kind_of := _not_regular(resolved):  # opening it would block (a FIFO) or never end (a device)
                raise FormatError(scene_path, f"{where}the file is {kind_of}, not a layer file (expected a regular "
                                              "file)")
            sub = _open_layer(scene_path, anchored, where)
            if sub.identifier not in seen:
                seen.add(sub.identifier)
                layers.append(sub)
                todo.append((sub, root_stack and kind == "subLayer"))
    return kept, layers, deferred


def _not_regular(resolved: str) -> str | None:
    """What the file at ``resolved`` is when it is there but no regular file ("a FIFO", ...);
    None for a regular file, a package's member or what cannot be stat'ed (opening says why)."""
    if Ar.IsPackageRelativePath(resolved):
        return None
    try:
        return not_regular(os.stat(resolved).st_mode)
    except OSError:
        return None


def layer_files(scene_path: Path) -> set[Path]:
    """The files (resolved) of every layer the scene's layer graph names through sublayers,
    references and payloads, itself excluded; what cannot be read is left out (converting
    the scene reports it)."""
    found: set[Path] = set()
    todo = [str(scene_path)]
    while todo:
        try:
            with usd_diagnostics([]):  # not printed: converting the scene reports them
                layer = Sdf.Layer.FindOrOpen(todo.pop())
        except Exception:  # pxr raises Tf.ErrorException, a plain Exception subclass
            continue
        if layer is None:
            continue
        for _kind, _site, authored, _prim, _offset in _arcs(layer):
            anchored = Sdf.ComputeAssetPathRelativeToLayer(layer, authored)
            file = Path(anchored)
            if "`" in authored or Ar.IsPackageRelativePath(anchored) or not file.is_file():
                continue
            file = file.resolve()
            if file not in found and file != Path(scene_path).resolve():
                found.add(file)
                if Sdf.FileFormat.FindByExtension(file.suffix.lstrip(".")) is not None:
                    todo.append(str(file))
    return found


_FAILED_ARC = re.compile(r"In <([^>]+)>: Could not open asset @([^@]+)@ for (reference|payload) introduced by "
                         r"@([^@]+)@<([^>]+)>")


def _landing(stage: Usd.Stage, message: str, candidate) -> Sdf.Path | None:
    """The stage path where USD says an arc of ``candidate`` ``(KeptArc, layer path)``
    failed to compose, or None when the message is not about it or that prim is inside
    an instance (where nothing can be authored)."""
    arc, layer = candidate
    m = _FAILED_ARC.search(message)
    if not m or m[2] != arc.resolved or m[3] != arc.kind or m[4] != layer or Sdf.Path(m[5]) != arc.site:
        return None
    prim = stage.GetPrimAtPath(m[1])
    if not prim or prim.IsInstanceProxy() or prim.IsInPrototype():
        return None
    return Sdf.Path(m[1])


def open_stage(path: Path, within: Path | None, messages: list[str]) -> UsdSource:
    """The composed stage of the scene at ``path`` after :func:`walk_layers`; USD's own
    diagnostics go to ``messages`` (those about kept arcs left out)."""
    kept, _layers, deferred = walk_layers(path, within)
    raw: list[str] = []
    try:
        with usd_diagnostics(raw):
            stage = Usd.Stage.Open(str(path))
    except Exception as e:
        why = usd_reason(str(e))
        raise FormatError(path, "not a readable USD stage" + (f": {why}" if why else "")) from None
    if stage is None:
        raise FormatError(path, "not a readable USD stage")
    missing = []
    for asset, refusal, candidate in deferred:
        hits = [m for m in raw if f"@{asset}@" in m]
        if not hits and candidate is None:
            missing.append(asset)  # the file an unselected variant names: none
        landed = [_landing(stage, m, candidate) for m in hits] if candidate else [None]
        if hits and None in landed:
            raise FormatError(path, refusal)
        kept.extend(dataclasses.replace(candidate[0], site=site) for site in dict.fromkeys(landed) if hits)
    known = [arc.resolved for arc in kept]
    messages.extend(m for m in raw if not any(k in m for k in known))
    return UsdSource(stage, kept, missing)


@dataclass
class AssetUse:
    """An authored asset value: its prim and attribute, the ``authored`` path, the
    ``resolved`` file ("" when it does not resolve) and, for a UDIM path
    (``<UDIM>``), the tiles found: tile number -> resolved file."""

    prim: Usd.Prim
    attr: Usd.Attribute
    authored: str
    resolved: str
    tiles: dict[int, str] = field(default_factory=dict)


UDIM_TILES = range(1001, 2000)


def asset_uses(stage: Usd.Stage):
    """Every authored asset value of the stage's prims, instance proxies included
    (:class:`AssetUse`)."""
    for prim in stage.Traverse(Usd.TraverseInstanceProxies()):
        for attr in prim.GetAttributes():
            if attr.GetTypeName() != Sdf.ValueTypeNames.Asset or not attr.HasAuthoredValue():
                continue
            value = attr.Get()
            if not isinstance(value, Sdf.AssetPath) or not value.path:
                continue
            use = AssetUse(prim, attr, value.path, value.resolvedPath)
            if "<UDIM>" in value.path:
                use.tiles = udim_tiles(attr, value.path)
            yield use


def udim_tiles(attr: Usd.Attribute, authored: str) -> dict[int, str]:
    """The tiles of the UDIM path ``authored`` (``<UDIM>`` in it) that the attribute ``attr``
    holding it resolves, anchored at the layer that authors it: tile -> resolved file."""
    anchored = anchored_path(attr, authored)
    tiles = {}
    for tile in UDIM_TILES:
        found = str(Ar.GetResolver().Resolve(anchored.replace("<UDIM>", str(tile))))
        if found:
            tiles[tile] = found
    return tiles


def anchored_path(attr: Usd.Attribute, authored: str) -> str:
    """``authored`` anchored at the layer that authors it on ``attr`` (where a file would be)."""
    specs = attr.GetPropertyStack()
    return Sdf.ComputeAssetPathRelativeToLayer(specs[0].layer, authored) if specs else authored


def asset_bytes(resolved: str) -> bytes | None:
    """The bytes of a resolved asset (a file, or a file inside a package); None if unreadable."""
    asset = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
    return None if asset is None else bytes(asset.GetBuffer())


def check_assets(scene, stage: Usd.Stage, within: Path | None) -> list[tuple[Path, str]]:
    """Refuse asset values that leave ``within`` (the project root); record the layers and files read
    in ``scene.inputs``. Returns ``(where a file would be, CSM404 text)`` of each value resolving to
    nothing, for :func:`warn_unresolved_assets` once the height textures are read."""
    missing = []
    layers = [Path(layer.realPath) for layer in stage.GetUsedLayers() if layer.realPath]
    for file in layers:
        if not Ar.IsPackageRelativePath(str(file)) and file.is_file() and file not in scene.inputs:
            scene.inputs.append(file)
    for use in asset_uses(stage):
        where = f"{use.prim.GetPath()}.{use.attr.GetName()} "
        references.check(scene.path, use.authored, where)  # resolved or not: never a URL kept
        files = list(use.tiles.values()) or [use.resolved] * bool(use.resolved)
        for resolved in files:
            refuse_asset(scene.path, use.authored, resolved, within, where)
            file = Path(resolved)
            if not Ar.IsPackageRelativePath(resolved) and file.is_file() and file not in scene.inputs:
                scene.inputs.append(file)  # (files inside a .usdz are the package's)
        if not files:
            place = anchored_path(use.attr, use.authored)
            if os.path.isabs(place) and not Ar.IsPackageRelativePath(place):
                scene.absent.append(Path(place))  # a UDIM set with no tile: its pattern
            what = "no UDIM tile" if "<UDIM>" in use.authored else "nothing"
            missing.append((Path(place), f"{where}names {use.authored!r}, which resolves to {what}; named where "
                                         f"the scene names it, so the output names a file it does not have"))
    for arc in getattr(scene.source, "kept", []):
        for resolved in (arc.resolved, *arc.files.values()):
            file = Path(resolved)
            if resolved and not Ar.IsPackageRelativePath(resolved) and file.is_file() and file not in scene.inputs:
                scene.inputs.append(file)
    return missing


def warn_unresolved_assets(scene, missing: list[tuple[Path, str]]) -> None:
    """A CSM404 for each of :func:`check_assets`' ``missing`` but a height texture a CSM101 named
    (``scene.said_missing``): one warning a missing file."""
    for place, text in missing:
        if place not in scene.said_missing:
            scene.warn("CSM404", text)

"""A scene's materials as the command line and the project configuration name them: the
check that every name given is one of them (:func:`check_names`, exit 2 listing the scene's
materials, how its format names them, and USD arcs a name may hide behind)."""

from __future__ import annotations

from pathlib import Path

from .errors import OptionError
from .scene import Scene


def check_names(scene: Scene, names, named_by: dict | None = None) -> None:
    """OptionError (exit 2) when a ``--height``/``--depth`` material name is not one of the
    scene's materials; the message lists them. ``named_by``: name -> where it was named (a
    configuration's ``file:line``), which the message then starts with."""
    known = {m.name for m in scene.materials} | {m.ref for m in scene.materials if isinstance(m.ref, str)}
    missing = sorted(set(names) - known)
    if missing:
        have = ", ".join(repr(m.name) for m in scene.materials) or "none"
        if getattr(scene.source, "default_faces", False):  # an OBJ's faces before any usemtl
            have += " (and the default material of the faces no usemtl names: =PATH gives it a height)"
        hint = UNNAMED.get(scene.format, "materials by name")
        where = (named_by or {}).get(missing[0])
        if where:
            same = [n for n in missing if (named_by or {}).get(n) == where]
            raise OptionError(f"{where}: names material {', '.join(map(repr, same))}, not a material of "
                              f"{scene.path}; its materials: {have} ({hint})" + behind_arcs(scene, same))
        raise OptionError(f"{scene.path}: --height/--depth-map/--depth name {', '.join(map(repr, missing))}, "
                          f"not a material of this scene; its materials: {have} ({hint})" + behind_arcs(scene, missing))


def behind_arcs(scene: Scene, missing) -> str:
    """Where the scene has arcs usd-core cannot compose (a MaterialX ``.mtlx`` reference; kept as
    authored, ``scene.source.kept``): which of the ``missing`` names sit behind one (the arc's
    prim by name or path, a path under it, or a material bound through it), else that they may."""
    kept = getattr(scene.source, "kept", None) or []
    if not kept:
        return ""

    def arc_text(arc):
        return f"the {arc.kind} {arc.authored!r} at <{arc.site}>"

    said = []
    for name in missing:
        arcs = [a for a in kept if name in (a.site.name, str(a.site)) or name.startswith(f"{a.site}/")
                or any(name in (t.name, str(t)) for t in a.bound)]
        if arcs:
            said.append(f"{name!r} is behind {arc_text(arcs[0])}")
    if said:
        return (f"; {'; '.join(said)}, which usd-core cannot read (no plugin for "
                f"{Path(kept[0].resolved).suffix or 'it'}): a material there cannot be given a height")
    return (f"; it may be behind {arc_text(kept[0])}" + (f" or {len(kept) - 1} other arc(s)" if len(kept) > 1 else "")
            + f", which usd-core cannot read (no plugin for {Path(kept[0].resolved).suffix or 'it'})")


_USD = "a USD material is named by its prim name or prim path"
UNNAMED = {"gltf": "an unnamed glTF material is material<index>, from 0",
           "glb": "an unnamed glTF material is material<index>, from 0",
           "obj": "OBJ materials are the MTL's newmtl names; =PATH names one whose name is empty", "usda": _USD, "usdc": _USD, "usdz": _USD, "usd": _USD}

"""MaterialX documents a USD scene references (kept arcs, see :mod:`.usd_assets`): the files
they name, checked like every other asset, and a copy rewritten to name flat copies.

A MaterialX ``filename`` input's file is its ``value`` after the ``fileprefix`` of the
nearest element that declares one, relative to the document. Missing files are warned
about (the document is copied as it was for them); files outside the project root are
refused unless allowed (see :func:`csm_assets.references.reach`).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from pxr import Ar

from ..errors import FormatError
from .usd_assets import asset_bytes, refuse_asset


def _parse(scene, resolved: str) -> ET.Element:
    data = asset_bytes(resolved)
    if data is None:
        raise FormatError(scene.path, f"the MaterialX document {resolved} cannot be read")
    try:
        return ET.fromstring(data)
    except ET.ParseError as e:
        raise FormatError(scene.path, f"the MaterialX document {resolved} is not valid XML: {e}") from None


def _filenames(root: ET.Element):
    """``(element, full authored path)`` of every filename input, fileprefix applied."""
    def walk(element, prefix):
        prefix = element.get("fileprefix", prefix)
        if element.get("type") == "filename" and element.get("value"):
            yield element, prefix + element.get("value")
        for child in element:
            yield from walk(child, prefix)
    yield from walk(root, "")


def mtlx_files(scene, resolved: str, within) -> dict[str, str]:
    """The files a MaterialX document names: authored path (fileprefix applied) ->
    resolved path ("" when missing, with a warning). FormatError for paths outside
    ``within`` (the project root; None: anywhere), absolute paths and URLs."""
    files = {}
    for _, authored in _filenames(_parse(scene, resolved)):
        if authored in files:
            continue
        anchored = Ar.GetResolver().CreateIdentifier(authored, Ar.ResolvedPath(resolved))
        refuse_asset(scene.path, authored, anchored, within, f"the MaterialX document {resolved} ")
        files[authored] = str(Ar.GetResolver().Resolve(anchored))
        if not files[authored]:
            scene.warn("CSM404", f"the MaterialX document {resolved} names {authored!r}, which does not exist; "
                       f"copied as it is")
    return files


def mtlx_copy(scene, resolved: str, files: dict[str, str], name_for) -> bytes:
    """The document's bytes with each existing file it names replaced by the flat name
    ``name_for(resolved file, authored path)`` gives (fileprefix attributes dropped)."""
    root = _parse(scene, resolved)
    elements = list(_filenames(root))
    for element in root.iter():
        element.attrib.pop("fileprefix", None)
    for element, authored in elements:
        found = files.get(authored, "")
        name = name_for(found, authored) if found else None
        element.set("value", name if name else authored)
    return ET.tostring(root, encoding="utf-8", xml_declaration=True)

"""The Python API reference (docs/reference/api/): every public name is on a page and documented.

The pages name objects with mkdocstrings' ``::: path`` (a module's ``members: [...]`` picks
some). Read as mkdocstrings reads them (griffe, Google style, as set in mkdocs.yml): each object
on a page, and each public member of a class on a page, has a docstring (a dataclass field may
be documented in its class's ``Attributes:`` section instead, which renders as a table), as has
every public function and class of the modules the pages render from; each
function or class taking parameters names every one in its ``Args:`` (or, for a dataclass,
``Attributes:``) section; and no docstring makes griffe warn (an unknown parameter, a missing
type), since ``mkdocs build --strict`` fails on those warnings too. Every name of
``csm_assets.__all__`` is on some page.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

import pytest

griffe = pytest.importorskip("griffe")

import csm_assets  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
API = ROOT / "docs" / "reference" / "api"
DIRECTIVE = re.compile(r"^::: ([\w.]+)\n((?:    .*\n)*)", re.M)


def _style() -> tuple[str, dict[str, bool]]:
    """mkdocs.yml's docstring style and its ``docstring_options`` (booleans)."""
    text = (ROOT / "mkdocs.yml").read_text(encoding="utf-8")
    options = text.split("docstring_options:", 1)[1] if "docstring_options:" in text else ""
    flags = re.findall(r"^ {14}(\w+): (true|false)$", options, re.M)
    return re.search(r"docstring_style: (\w+)", text).group(1), {k: v == "true" for k, v in flags}


STYLE, OPTIONS = _style()
PACKAGE = griffe.load("csm_assets", search_paths=[ROOT], docstring_parser=STYLE, resolve_aliases=True,
                      resolve_implicit=True)


def _get(path: str):
    return PACKAGE if path == "csm_assets" else PACKAGE[path.removeprefix("csm_assets.")]


def directives() -> list[tuple[str, str]]:
    """``(page, path)`` of every object the API pages name (a module's listed members one by one)."""
    found = []
    for page in sorted(API.glob("*.md")):
        for path, options in DIRECTIVE.findall(page.read_text(encoding="utf-8")):
            members = re.search(r"members: \[(.*)\]", options)
            names = [n.strip() for n in members.group(1).split(",")] if members else []
            found += [(page.name, f"{path}.{n}") for n in names] or [(page.name, path)]
    return found


def _real(obj):
    return obj.final_target if obj.is_alias else obj


def documented() -> dict[str, object]:
    """Every object the pages render, by path: the named ones and their classes' public members."""
    found: dict[str, object] = {}

    def walk(obj):
        obj = _real(obj)
        if obj.path in found:
            return
        found[obj.path] = obj
        if obj.is_class:
            for name, member in obj.members.items():
                if not name.startswith("_") and not member.is_alias:
                    walk(member)

    for _, path in directives():
        walk(_get(path))
    return found


OBJECTS = documented()


def _sections(obj, kind: str) -> dict[str, object]:
    if obj.docstring is None:
        return {}
    return {item.name.lstrip("*"): item for s in obj.docstring.parse(STYLE, **OPTIONS) if s.kind.value == kind
            for item in s.value}


def _parameters(obj) -> list[str]:
    if obj.is_function:
        params = obj.parameters
    elif obj.is_class and "__init__" in obj.all_members:
        params = _real(obj.all_members["__init__"]).parameters
    else:
        return []
    return [p.name for p in params if p.name not in ("self", "cls")]


def test_the_pages_name_objects_that_exist():
    assert len(OBJECTS) > 200, "the API pages render fewer objects than expected"


def test_every_name_in_all_is_on_an_api_page():
    named = {path for _, path in directives()}
    targets = {_real(_get(p)).path for p in named}
    missing = [n for n in csm_assets.__all__
               if f"csm_assets.{n}" not in named and _real(_get(f"csm_assets.{n}")).path not in targets]
    assert missing == [], f"exported but on no API page: {missing}"


def test_every_documented_object_has_a_docstring():
    bare = []
    for path, obj in OBJECTS.items():
        if obj.docstring and obj.docstring.value.strip():
            continue
        parent = obj.parent
        if obj.is_attribute and parent.is_class and obj.name in _sections(parent, "attributes"):
            continue  # a field in its class's Attributes section
        bare.append(path)
    assert bare == [], f"{len(bare)} public objects without a docstring: {bare}"


def test_every_public_function_and_class_of_the_documented_modules_has_a_docstring():
    """Beyond what the pages render: each module they render from has no public function or
    class (defined there, not imported) without a docstring."""
    modules = {}
    for _, path in directives():
        obj = _real(_get(path))
        module = obj if obj.is_module else obj.module
        modules[module.path] = module
    bare = [f"{path}.{name}" for path, module in sorted(modules.items()) for name, member in module.members.items()
            if not name.startswith("_") and not member.is_alias and (member.is_function or member.is_class)
            and not (member.docstring and member.docstring.value.strip())]
    assert len(modules) > 30 and bare == [], f"undocumented: {bare}"


def test_every_parameter_is_documented():
    missing = []
    for path, obj in OBJECTS.items():
        names = _parameters(obj)
        if not names or obj.docstring is None:
            continue
        given = set(_sections(obj, "parameters")) | (set(_sections(obj, "attributes")) if obj.is_class else set())
        if obj.is_class and "__init__" in obj.all_members and _real(obj.all_members["__init__"]).docstring:
            given |= set(_sections(_real(obj.all_members["__init__"]), "parameters"))
        lacking = [n for n in names if n not in given]
        if lacking:
            missing.append(f"{path}: {', '.join(lacking)}")
    assert missing == [], "parameters missing from the Args section:\n" + "\n".join(missing)


def test_docstrings_parse_without_warnings():
    """griffe's warnings (a documented parameter the signature lacks, no type anywhere, a bad
    section) are what make ``mkdocs build --strict`` fail on an API page."""
    records: list[str] = []

    class Collect(logging.Handler):
        def emit(self, record):
            records.append(record.getMessage())

    logger = logging.getLogger("griffe")
    handler = Collect(level=logging.WARNING)
    logger.addHandler(handler)
    try:
        for obj in OBJECTS.values():
            if obj.docstring is not None:
                obj.docstring.parse(STYLE, **OPTIONS)
    finally:
        logger.removeHandler(handler)
    assert records == []


def test_the_style_is_one_griffe_parses():
    """mkdocs.yml's style is the one the docstrings are written in: parameter sections parse."""
    assert STYLE == "google" and OPTIONS == {"returns_multiple_items": False, "warn_missing_types": False}
    assert _sections(OBJECTS["csm_assets.cones.exact.cone_ratios"], "parameters")

"""Every warning the library emits, as data: a stable code, a severity and a one-line
meaning (:data:`RULES`, one table, as linters and the Khronos glTF validator keep theirs;
``docs/reference/warnings.md`` is made from it), the warnings themselves
(:class:`Notice`, collapsed with a count by :func:`add`) and what fails a run
(:class:`Policy`: ``--strict``, ``--error-on``, ``--ignore``).

Severities: ``info`` (the output is as intended; worth knowing) and ``warning`` (the output
may be wrong or incomplete). Codes never change meaning; a retired code is not reused.
"""

from __future__ import annotations

import contextlib
import dataclasses
import threading
import warnings
from dataclasses import dataclass

from .printable import printable

INFO, WARNING = "info", "warning"


@dataclass(frozen=True)
class Rule:
    code: str
    name: str
    severity: str  # INFO or WARNING
    meaning: str


RULES = (
    Rule("CSM000", "unclassified", WARNING, "A warning recorded by a csm-assets without codes (an older manifest); "
         "convert with --force to classify it."),
    # height textures: finding and reading the relief
    Rule("CSM101", "height-missing", WARNING, "A height texture the scene names is missing; its material gets no CSM."),
    Rule("CSM102", "height-unreadable", WARNING, "A height texture cannot be read (a broken image or data URI, a file a "
         ".usdz package does not give); its material gets no CSM."),
    Rule("CSM103", "height-no-texture", WARNING, "A material's height slot names no usable texture (no texture index, "
         "no image, no file, a source other than UsdUVTexture, a scale or bias of the wrong type); it gets no CSM."),
    Rule("CSM104", "shader-graph", WARNING, "A USD material's shader connections form a cycle or lead nowhere; "
         "it gets no CSM."),
    Rule("CSM105", "height-udim", WARNING, "Retired: UDIM height sets are converted (a step map per tile; see "
         "CSM108); no longer emitted, still accepted by --ignore and --error-on."),
    Rule("CSM106", "normal-map", WARNING, "A height slot holds a tangent-space normal map, not heights; skipped, "
         "its material gets no CSM."),
    Rule("CSM107", "colour-height", WARNING, "A height texture is a colour image, not grey heights; its luminance "
         "(or the channel read) is used, which may not be the relief meant."),
    Rule("CSM108", "udim-uncovered", WARNING, "A UDIM height set's mesh has triangles in a tile the set lacks "
         "(no relief there) or reaching across their tile's border (the relief is cut off at it)."),
    # meshes and tangents
    Rule("CSM201", "no-normals", WARNING, "A mesh has no normals, so it gets no tangents (viewers ignore tangents "
         "without normals)."),
    Rule("CSM202", "no-uvs", WARNING, "A mesh or primitive lacks the positions or uvs its relief needs; it gets "
         "no tangents (OBJ: its material gets no CSM)."),
    Rule("CSM203", "material-undrawn", WARNING, "No mesh of a material has triangles with positions and uvs, so "
         "the material gets no CSM."),
    Rule("CSM204", "not-triangles", WARNING, "A glTF primitive is not a triangle list (points, lines, strips, "
         "fans); it gets no tangents."),
    Rule("CSM205", "degenerate-triangles", INFO, "Triangles without area or without uv area (common in real "
         "meshes), counted per mesh: they show no relief, and MikkTSpace borrows their tangents from their "
         "neighbours."),
    Rule("CSM206", "non-manifold", INFO, "Edges shared by more than two triangles; their tangents are as "
         "MikkTSpace makes them."),
    Rule("CSM207", "short-faces", INFO, "Faces with fewer than three vertices (an OBJ face of one or two, a USD "
         "faceVertexCount of 0, 1 or 2) are skipped, counted per mesh (they draw nothing)."),
    Rule("CSM208", "subdivision", INFO, "A USD subdivision surface (catmullClark is USD's default scheme); its "
         "tangents are made on the control cage and approximate the limit surface's."),
    Rule("CSM209", "tangents-replaced", INFO, "Tangents the file carries do not fit the mesh or hold NaN, "
         "infinite or zero vectors; new ones are made."),
    Rule("CSM210", "uvs-outside", WARNING, "uvs outside [0, 1] on an axis the step map does not tile: the relief "
         "is cut off there and verify cannot measure it (convert with --tile if the texture repeats)."),
    Rule("CSM211", "compression-dropped", WARNING, "Compressed geometry (Draco, meshopt) that csm-assets cannot "
         "encode again is written uncompressed, so the output grows; the message names it and the input's and "
         "output's size (--ignore CSM211 accepts it)."),
    # step maps and picks
    Rule("CSM301", "narrow-cones", WARNING, "Cones narrower than one step of the stored format are stored as one "
         "step, wider than exact: rays may pass through the surface (lower --max-ratio or use more bits)."),
    Rule("CSM302", "budget-unmet", WARNING, "No shader setting meets --max-error at verify's views; the first "
         "pick is written."),
    Rule("CSM303", "bits-raised", INFO, "An 8-bit step map cannot meet --max-error; the map is written at "
         "16 bits."),
    Rule("CSM304", "bits-too-few", WARNING, "The step map's bits round heights more coarsely than verify's default "
         "views allow (--bits given, or no bit depth is enough): the map may fail verify."),
    # USD stages
    Rule("CSM401", "usd-diagnostic", WARNING, "USD itself reported a problem while reading or writing the stage "
         "(its message follows)."),
    Rule("CSM402", "arc-unreadable", WARNING, "A sublayer, reference or payload usd-core cannot read (MaterialX "
         "without its plugin) is kept as authored and copied; materials bound through it get no CSM."),
    Rule("CSM403", "variants-flattened", WARNING, "The output is flattened to the current variant selections; "
         "the other variants are not in it."),
    Rule("CSM404", "asset-unresolved", WARNING, "An asset path (a USD asset, a glTF image, an MTL map) resolves to "
         "no file; the output names it where the scene does, so it names a file it does not have until the file "
         "is there. A missing height texture is a CSM101 alone."),
    # the viewer
    Rule("CSM501", "view-outside", WARNING, "A file the scene names lies outside its project root; view does not "
         "serve it."),
    Rule("CSM502", "view-missing", WARNING, "A buffer or image the scene names is missing; view shows the scene "
         "without it."),
    Rule("CSM503", "view-no-csm", INFO, "No material carries EXT_materials_cone_step_mapping; view shows the "
         "scene without relief (convert it first)."),
    Rule("CSM504", "view-bad-extension", WARNING, "A material's EXT_materials_cone_step_mapping breaks the extension's "
         "schema (a wrong type, a number out of range or past the shader's 32-bit floats, an unknown variant); view "
         "shows that material without relief (the plain material)."),
    Rule("CSM505", "view-bad-levels", WARNING, "A material's levels image (stepMapLevelsTexture, "
         "stepMap2LevelsTexture) cannot be read or is not the documented size and type for its step map; the page "
         "draws that step map's level 0 alone."),
    # anything else
    Rule("CSM900", "library-warning", WARNING, "A warning from Python or a library (numpy, ...) that csm-assets "
         "does not classify; its category and text follow."),
)
BY_CODE = {r.code: r for r in RULES}
SHOWN = 3  # subjects named in a collapsed line before "and N more"
_CAPTURE = threading.Lock()  # one python_warnings block at a time


class CodedWarning(UserWarning):
    """A Python warning (``warnings.warn``) from a kernel that knows no scene; its class names
    its code, and ``convert`` turns it into a :class:`Notice` of the scene."""

    code = "CSM900"


class NarrowCones(CodedWarning, RuntimeWarning):
    code = "CSM301"


@dataclass(frozen=True)
class Notice:
    """One warning as emitted: ``code``, the file it is about (``where``), what was found
    (``text``, the same for each subject), the meshes or materials it is about (``about``,
    may be empty) and how many times it was said (``count``)."""

    code: str
    where: str
    text: str
    about: tuple[str, ...] = ()
    count: int = 1

    @property
    def rule(self) -> Rule:
        return BY_CODE[self.code]

    @property
    def severity(self) -> str:
        return self.rule.severity

    @property
    def message(self) -> str:
        """One line: ``where: [N x ]subjects: text``, the first :data:`SHOWN` subjects named."""
        names = ", ".join(self.about[:SHOWN]) + (f" and {len(self.about) - SHOWN} more"
                                                 if len(self.about) > SHOWN else "")
        times = f"{self.count} x " if self.count > 1 else ""
        return f"{self.where}: {times}{names + ': ' if names else ''}{self.text}"

    def __str__(self) -> str:
        return f"{self.code} {self.message}"

    def to_dict(self) -> dict:
        return {"code": self.code, "name": self.rule.name, "severity": self.severity, "message": self.message,
                "count": self.count, "about": list(self.about)}

    @classmethod
    def from_dict(cls, d) -> "Notice":
        """A notice as :meth:`to_dict` (or a manifest) holds it; a bare string (a manifest
        written before codes) is CSM000."""
        if isinstance(d, str):
            where, _, text = d.partition(": ")
            return cls("CSM000", where, text) if text else cls("CSM000", "", d)
        code = d["code"] if d.get("code") in BY_CODE else "CSM000"
        where, about = d.get("where", ""), tuple(d.get("about", ()))
        return cls(code, where, d.get("text", d.get("message", "")), about, int(d.get("count", 1)))

    def record(self) -> dict:
        """What a manifest keeps (enough for :meth:`from_dict`)."""
        return {"code": self.code, "where": self.where, "text": self.text, "about": list(self.about),
                "count": self.count}


def add(notices: list, notice: Notice) -> None:
    """Append ``notice`` to ``notices``, or fold it into one of the same code, file and text:
    its count grows by the new one's and its subjects are joined (in order, each once)."""
    for i, n in enumerate(notices):
        if (n.code, n.where, n.text) == (notice.code, notice.where, notice.text):
            about = n.about + tuple(a for a in notice.about if a not in n.about)
            notices[i] = Notice(n.code, n.where, n.text, about, n.count + notice.count)
            return
    notices.append(notice)


def recorded(entry: dict, scene) -> list[Notice]:
    """The warnings a manifest ``entry`` recorded (:meth:`Notice.record`), each about ``scene`` as
    this run names it (the entry holds the path the converting run gave, from its own folder)."""
    return [dataclasses.replace(Notice.from_dict(d), where=str(scene)) for d in entry.get("warnings", [])]


def checked_codes(codes, what: str) -> tuple[str, ...]:
    """``codes`` (an iterable of code strings, any case; a lone string is one code) as a tuple of
    known codes; ValueError naming ``what`` (the option or config key) and the unknown ones."""
    if isinstance(codes, str):
        codes = [codes]
    out = []
    for c in codes or ():
        if not isinstance(c, str):
            raise ValueError(f"{what}: a warning code is text like CSM205, got {c!r}")
        code = c.strip().upper()
        if code not in BY_CODE:
            raise ValueError(f"{what}: {c!r} is not a warning code (codes look like CSM205; the table: "
                             "docs/reference/warnings.md)")
        if code not in out:
            out.append(code)
    return tuple(out)


@dataclass(frozen=True)
class Policy:
    """Which warnings fail a run: ``error_on`` codes always, every ``warning``-severity code
    under ``strict``, ``ignore``d codes never (they are not reported either)."""

    strict: bool = False
    error_on: tuple[str, ...] = ()
    ignore: tuple[str, ...] = ()

    @classmethod
    def of(cls, opts) -> "Policy":
        """The policy of a :class:`~csm_assets.convert.pipeline.ConvertOptions`."""
        return cls(bool(getattr(opts, "strict", False)), tuple(getattr(opts, "error_on", ()) or ()),
                   tuple(getattr(opts, "ignore", ()) or ()))

    def level(self, code: str) -> str:
        """``ignore``, ``info``, ``warning`` or ``error``: how a notice of ``code`` counts."""
        if code in self.ignore:
            return "ignore"
        severity = BY_CODE[code].severity
        if code in self.error_on or (self.strict and severity == WARNING):
            return "error"
        return severity

    def kept(self, notices) -> list:
        """The notices that are reported (not ignored)."""
        return [n for n in notices if self.level(n.code) != "ignore"]

    def failing(self, notices) -> list:
        """The notices that fail the run."""
        return [n for n in notices if self.level(n.code) == "error"]

    def why(self, failing) -> str:
        """The options that made ``failing`` errors, for the message."""
        promoted = any(n.code in self.error_on for n in failing)
        strict = any(n.code not in self.error_on for n in failing)
        return " and ".join(x for x, on in (("--strict", strict), ("--error-on", promoted)) if on)


def line(notice: Notice) -> str:
    """``notice`` as the CLI prints it: ``csm-assets: SEVERITY: CODE where: ...`` and a newline
    (a run that --strict or --error-on fails says so in its one error line, naming the codes)."""
    return f"csm-assets: {notice.severity}: {printable(notice)}\n"


@contextlib.contextmanager
def python_warnings(scene):
    """Python warnings (``warnings.warn``) raised while the block runs become warnings of ``scene``:
    a :class:`CodedWarning`'s own code (each time, not once per place), else CSM900 with the
    category's name. Python's warning machinery is one per process, so one such block runs at a
    time (a lock); other code's ``catch_warnings`` in another thread meanwhile can still take them."""
    with _CAPTURE, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", CodedWarning)
        yield
    for w in caught:
        text = " ".join(str(w.message).split())
        if issubclass(w.category, CodedWarning):
            code = w.category.code
        else:
            code, text = "CSM900", f"{w.category.__name__}: {text}"
        scene.warn(code, text)


def markdown_table() -> str:
    """The code table of ``docs/reference/warnings.md`` (a test keeps the page equal to it)."""
    rows = ["| Code | Name | Severity | Meaning |", "| --- | --- | --- | --- |"]
    rows += [f"| `{r.code}` | {r.name} | {r.severity} | {r.meaning.replace('|', '/')} |" for r in RULES]
    return "\n".join(rows) + "\n"

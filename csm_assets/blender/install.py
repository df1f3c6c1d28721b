"""``csm-assets blender install``: put the add-on into a Blender's add-ons folder and enable it.

Blender loads add-ons from ``<user scripts>/addons/<name>/``; this writes there a small package
:data:`ADDON` whose ``__init__.py`` holds the add-on's ``bl_info`` (Blender reads it without
importing) and loads :mod:`csm_assets.blender` from the Python environment csm-assets is installed
in (its folders are appended to Blender's ``sys.path``, so Blender's own modules come first). Then
Blender itself enables it and saves its preferences. Blender and this environment must run the
same Python minor version (Blender 4.2 to 5.0 run 3.11), as compiled modules (numpy, numba,
OpenImageIO) are shared.

The Blender is an executable (``--blender``, else ``blender`` on PATH: its preferences are loaded at
start), else the ``bpy`` module of this Python (Blender from PyPI: its saved preferences are read
first, so the user's other settings stay; scripts then load them with ``bpy.ops.wm.read_userpref()``,
or call :func:`csm_assets.blender.enable`). bpy 4.2 as a module crashes reading preferences: there
the add-on is enabled only when no preferences were saved before (nothing to overwrite). Nothing
here imports bpy: Blender runs in a subprocess.
"""

from __future__ import annotations

import errno
import importlib.util
import json
import os
import shutil
import stat
import subprocess
import sys
import sysconfig
from dataclasses import dataclass
from pathlib import Path

from .. import __version__
from ..atomic import atomic_path
from ..errors import OptionError, OutputError

ADDON = "csm_assets_gltf"
MARKER = "CSM-ASSETS-INSTALL "
HEADER = "# Written by `csm-assets blender install`"

INFO = """
import bpy, json, sys
print({marker!r} + json.dumps({{"addons": bpy.utils.user_resource("SCRIPTS", path="addons", create=True),
    "prefs": bpy.utils.user_resource("CONFIG", path="userpref.blend"),
    "python": list(sys.version_info[:2]), "blender": bpy.app.version_string}}), flush=True)
"""
READ_PREFS = """
import bpy, json
bpy.ops.wm.read_userpref()
print({marker!r} + json.dumps({{"read": True}}), flush=True)
"""
ENABLE = """
import bpy
import addon_utils, json
if {read_prefs!r}:
    bpy.ops.wm.read_userpref()
bpy.utils.refresh_script_paths()
module = addon_utils.enable({addon!r}, default_set=True)
enabled = module is not None and {addon!r} in bpy.context.preferences.addons
if enabled:
    bpy.ops.wm.save_userpref()
print({marker!r} + json.dumps({{"enabled": enabled}}), flush=True)
"""


@dataclass
class InstallReport:
    """Where the add-on went (``folder``), into which Blender (``blender``: its version,
    ``command``: how it was run) and whether Blender enabled it."""

    folder: Path
    blender: str
    command: list
    enabled: bool


def blender_command(blender=None) -> list[str]:
    """How to run Python in the target Blender: ``[exe, --background, --python-expr]`` for an
    executable, ``[python, -c]`` for this Python's bpy module. OptionError when there is neither."""
    exe = blender or shutil.which("blender")
    if exe is not None:
        if shutil.which(str(exe)) is None:
            path = Path(exe)
            why = ("is a folder, not the Blender executable" if path.is_dir() else
                   "is not executable (give the Blender executable)" if path.exists() else "no such Blender executable")
            raise OptionError(f"{exe}: {why}")
        return [str(exe), "--background", "--python-exit-code", "1", "--python-expr"]
    if importlib.util.find_spec("bpy") is not None:
        return [sys.executable, "-c"]
    raise OptionError("no Blender found: give its executable with --blender PATH (or put blender on PATH, "
                      "or pip install bpy into this Python to use Blender as a module)")


def run_in_blender(command: list[str], code: str, timeout: float = 300) -> dict:
    """Run ``code`` in Blender; the JSON it printed after :data:`MARKER`. OutputError when it fails."""
    r = subprocess.run([*command, code], capture_output=True, text=True, timeout=timeout)
    for line in r.stdout.splitlines():
        if line.startswith(MARKER):
            return json.loads(line[len(MARKER):])
    tail = " | ".join((r.stderr or r.stdout).strip().splitlines()[-3:])
    raise OutputError(command[0], f"Blender failed (exit {r.returncode}): {tail}")


def prefs_readable(command: list[str], timeout: float) -> bool:
    """Whether this Blender module loads its saved preferences (bpy 4.2 as a module crashes there)."""
    try:
        return bool(run_in_blender(command, READ_PREFS.format(marker=MARKER), timeout).get("read"))
    except OutputError:
        return False


def environment_paths() -> list[str]:
    """The folders Blender needs on its path to import csm_assets and its dependencies here."""
    import csm_assets

    paths = [str(Path(csm_assets.__file__).resolve().parents[1])]
    for key in ("purelib", "platlib"):
        paths.append(sysconfig.get_paths()[key])
    return list(dict.fromkeys(paths))


def addon_source(paths: list[str]) -> str:
    """The add-on package's ``__init__.py``: bl_info as a literal, then csm_assets.blender's entry points."""
    from . import bl_info

    return "\n".join([
        f"{HEADER} (csm-assets {__version__}): Blender's add-on entry for",
        "# csm_assets.blender, loaded from the Python environment csm-assets is installed in.",
        f"bl_info = {bl_info!r}",
        "",
        "import sys",
        "",
        f"for _path in {paths!r}:",
        "    if _path not in sys.path:",
        "        sys.path.append(_path)",
        "",
        "from csm_assets.blender import (  # noqa: E402",
        "    draw_import, glTF2_post_export_callback, glTF2_pre_export_callback, glTF2ExportUserExtension,",
        "    glTF2ImportUserExtension, register, unregister)",
        "",
    ])


def check_folder(addons: Path) -> None:
    """OutputError unless ``addons``/:data:`ADDON` is absent or ours to overwrite: a folder (a link to
    one is followed only inside ``addons``) whose ``__init__.py`` is a regular file (not a link, FIFO
    or device: opened without following links or blocking, its first bytes only) starting with
    :data:`HEADER`. A folder of that name without it is someone else's."""
    folder = addons / ADDON
    if not os.path.lexists(folder):
        return
    if folder.is_symlink():
        try:
            target = folder.resolve(strict=True)
        except (OSError, RuntimeError):  # dangling, or a loop
            raise OutputError(folder, "is a link that leads nowhere; remove it first") from None
        if not target.is_relative_to(addons.resolve()):
            raise OutputError(folder, f"is a link to {target}, outside {addons}; remove it first")
    if not folder.is_dir():
        raise OutputError(folder, "exists and is not a folder; remove it first")
    init = folder / "__init__.py"
    if not os.path.lexists(init):
        raise OutputError(folder, "exists and was not written by csm-assets (it has no __init__.py); remove it first")
    try:
        fd = os.open(init, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError as e:
        why = "is a link" if e.errno == errno.ELOOP else f"cannot be read ({e.strerror})"
        raise OutputError(init, f"{why}, not a file csm-assets wrote; remove {folder} first") from None
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            raise OutputError(init, f"is not a regular file; remove {folder} first")
        head = f.read(len(HEADER.encode()))
    if head != HEADER.encode():
        raise OutputError(init, f"exists and was not written by csm-assets; remove {folder} first")


def install(blender=None, *, timeout: float = 300) -> InstallReport:
    """Install the add-on into ``blender`` (see the module docstring) and enable it there."""
    command = blender_command(blender)
    module = command[0] == sys.executable and command[1] == "-c"  # bpy from PyPI: preferences not loaded
    info = run_in_blender(command, INFO.format(marker=MARKER), timeout)
    theirs, ours = tuple(info["python"]), tuple(sys.version_info[:2])
    if theirs != ours:
        raise OptionError(f"Blender {info['blender']} runs Python {theirs[0]}.{theirs[1]}, this csm-assets "
                          f"Python {ours[0]}.{ours[1]}: install csm-assets with a Python {theirs[0]}.{theirs[1]} "
                          "(or into Blender's own Python) and run this from there")
    folder = Path(info["addons"]) / ADDON
    init = folder / "__init__.py"
    check_folder(Path(info["addons"]))
    folder.mkdir(parents=True, exist_ok=True)
    with atomic_path(init) as tmp:
        tmp.write_text(addon_source(environment_paths()), encoding="utf-8")
    read_prefs = module and prefs_readable(command, timeout)
    if module and not read_prefs and Path(info["prefs"]).exists():
        raise OutputError(info["prefs"], f"this bpy ({info['blender']}) cannot read Blender's saved preferences (it "
                                         "crashes), so enabling the add-on there would overwrite them; the add-on is "
                                         f"in {folder}: call csm_assets.blender.enable() in your scripts instead")
    done = run_in_blender(command, ENABLE.format(addon=ADDON, marker=MARKER, read_prefs=read_prefs), timeout)
    return InstallReport(folder, info["blender"], command, bool(done["enabled"]))

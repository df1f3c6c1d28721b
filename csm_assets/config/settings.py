"""A scene's settings: the defaults, then its project configuration (the table of every
scene, then each ``[scenes."GLOB"]`` table that matches it, in the file's order), then
the command line; each setting keeps where it came from (``config show``).

:class:`Resolver` loads each configuration once and gives each scene its
:class:`~csm_assets.convert.pipeline.ConvertOptions` (:meth:`Resolver.options`) or the
settings behind them (:meth:`Resolver.settings`).
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ..convert.options import ConvertOptions, check_material_options, check_warning_options
from ..convert.pick import default_variant
from ..errors import OptionError
from .files import find_config, repository_root, scene_folder
from .load import ProjectConfig, Value, load, option_fields

DEFAULT = "default"
COMMAND_LINE = "command line"


@dataclass(frozen=True)
class Setting:
    """One setting of a scene: ``key`` as a configuration writes it, the ``value`` and its
    ``source``: "default", a configuration's ``file:line`` or "command line"."""

    key: str
    value: Any
    source: str


@dataclass
class SceneSettings:
    """Everything that applies to one scene: the ``config`` file (None: none), the project
    ``root`` (None: found from the scene) and the settings by target (see :class:`Value`)."""

    scene: Path
    config: Path | None
    root: Path | None
    settings: dict[Any, Setting]

    def options(self, **extra) -> ConvertOptions:
        """The :class:`ConvertOptions` of these settings (``extra``: fields the caller sets,
        such as ``force``). OptionError (exit 2) for settings that do not go together,
        naming where the settings came from."""
        plain = {k: s.value for k, s in self.settings.items() if isinstance(k, str)}
        heights = {k[1]: s.value for k, s in self.settings.items() if isinstance(k, tuple) and k[0] == "heights"}
        depths = {k[1]: s.value for k, s in self.settings.items() if isinstance(k, tuple) and k[0] == "depths"}
        named_by: dict[str, str] = {}  # a material's first mention in the configuration
        for k, s in self.settings.items():
            if isinstance(k, tuple) and s.source not in (DEFAULT, COMMAND_LINE):
                named_by.setdefault(k[1], s.source)
        depth_names = {k if isinstance(k, str) else k[1]: _depth_name(s) for k, s in self.settings.items()
                       if k == "depth" or isinstance(k, tuple) and k[0] == "depths"}
        opts = ConvertOptions(**{**plain, "heights": heights, "depths": depths, "root": self.root,
                                 "named_by": named_by, "depth_names": depth_names, **extra})
        size = self.settings["light_size"]
        if isinstance(size.value, (int, float)) and size.value > 0 and not opts.self_shadow:
            raise OptionError(f"light-size {size.value:g} ({size.source}) is the soft shadows' light size: it "
                              "needs --self-shadow (or self-shadow = true in the configuration)")
        try:
            check_material_options(opts)
            check_warning_options(opts, (_named(self.settings["error_on"]), _named(self.settings["ignore"])))
        except OptionError as e:
            given = [f"{s.key} ({s.source})" for s in self.settings.values() if s.source != DEFAULT]
            raise OptionError(f"{self.scene}: {e}; its settings: {', '.join(given) or 'the defaults'}") from None
        return opts


def _named(s: Setting) -> str:
    """A setting as a message names it: its flag (``--error-on``) when the command line gave
    it, else its key and where it was set."""
    return f"--{s.key}" if s.source == COMMAND_LINE else s.key if s.source == DEFAULT else f"{s.key} ({s.source})"


def _depth_name(s: Setting) -> str:
    """How a refused depth's message names its setting: ``--depth``, ``--depth MATERIAL=D`` or the
    configuration key and where it was set (``depth.Hull (csm-assets.toml:4)``)."""
    if s.source == COMMAND_LINE:
        return "--depth" if s.key == "depth" else f"--depth {s.key.split('.', 1)[1]}=D"
    return _named(s)


def command_line_values(given: dict[str, Any], heights: dict, depth, depths: dict) -> list[Value]:
    """The command line's settings as :class:`Value` s: ``given`` (ConvertOptions field ->
    value, only the flags given), the ``--height``/``--depth-map`` textures by material,
    ``--depth`` D and ``--depth MATERIAL=D``."""
    keys = {f.name: key for key, f in option_fields().items()}
    out = [Value(keys.get(name, name), name, value, COMMAND_LINE) for name, value in given.items()]
    out += [Value(f"{'depth-map' if getattr(spec, 'depth_map', False) else 'height'}.{m}", ("heights", m), spec,
                  COMMAND_LINE) for m, spec in heights.items()]
    if depth is not None:
        out.append(Value("depth", "depth", depth, COMMAND_LINE))
    out += [Value(f"depth.{m}", ("depths", m), d, COMMAND_LINE) for m, d in depths.items()]
    return out


class Resolver:
    """Settings per scene for one run: the command line's flags over each scene's configuration.

    Args:
        given: the command line's :class:`Value` objects (they win over the configuration).
        config (str | os.PathLike | None): a configuration file for every scene; None: each
            scene's own, found walking up from it.
        check: the command line's checks of a configuration's values (see :func:`.load.load`).

    Attributes:
        loaded (dict): configurations read so far, by resolved path (each read once a run).
    """

    def __init__(self, given: list[Value] = (), config=None, check: Callable | None = None):
        self.given, self.config, self.check = list(given), config, check
        self.loaded: dict[Path, ProjectConfig] = {}

    def project(self, scene) -> ProjectConfig | None:
        """The configuration that applies to ``scene`` (read once), or None.

        Args:
            scene (str | os.PathLike): the scene file.

        Raises:
            ConfigError: the configuration cannot be read or holds a bad value (an
                OptionError, exit 2).
        """
        path = Path(self.config) if self.config is not None else find_config(scene)
        if path is None:
            return None
        key = os.path.realpath(path)  # a link loop: load says so
        if key not in self.loaded:
            self.loaded[key] = load(path, self.check)
        return self.loaded[key]

    def settings(self, scene) -> SceneSettings:
        """Every setting for ``scene`` with where it comes from (what ``config show`` prints).

        Args:
            scene (str | os.PathLike): the scene file.

        Raises:
            ConfigError: the configuration cannot be read, holds a bad value, or names a
                texture that is gone (an OptionError, exit 2).
        """
        project = self.project(scene)
        chosen: dict[Any, Setting] = {f.name: Setting(key, f.default if f.default is not dataclasses.MISSING
                                                      else f.default_factory(), DEFAULT)
                                      for key, f in option_fields().items()}
        sections = project.applying(scene) if project else []
        for problem in (p for sec in sections for p in sec.problems):
            raise problem  # a texture it names is gone: this scene fails, the others go on
        for value in [v for sec in sections for v in sec.values] + self.given:
            chosen[value.target] = Setting(value.key, value.value, value.where)
        _default_variant(chosen)
        return SceneSettings(Path(scene), project.path if project else None, _root(scene, project), chosen)

    def options(self, scene, **extra) -> ConvertOptions:
        """:meth:`settings` as the :class:`~csm_assets.convert.options.ConvertOptions` of ``scene``.

        Args:
            scene (str | os.PathLike): the scene file.
            **extra: fields no setting decides (``force``, ``cache_dir``, ...).
        """
        return self.settings(scene).options(**extra)


def _root(scene, project: ProjectConfig | None) -> Path | None:
    """The configuration's folder, where the scene lies below it (a ``--config`` elsewhere:
    the repository's root or the scene's folder); None without a configuration (found)."""
    if project is None:
        return None
    if Path(scene).resolve().is_relative_to(project.folder):
        return project.folder
    return repository_root(scene) or scene_folder(scene)


def _default_variant(chosen: dict[Any, Setting]) -> None:
    """The variant nobody chose follows the other settings, as on the command line: "auto"
    with a max-error budget, "relaxed" with relaxed cones, "quadrant" with quadrant cones, else the default."""
    if chosen["variant"].source != DEFAULT:
        return
    variant = default_variant(chosen["max_error"].value, chosen["cones"].value)
    if variant != chosen["variant"].value:
        why = "with max-error" if chosen["max_error"].value is not None else f"with {chosen['cones'].value} cones"
        chosen["variant"] = Setting("variant", variant, f"{DEFAULT} ({why})")

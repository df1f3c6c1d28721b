"""Shared USD test helpers: the sample wall's files, stage edits, UsdValidation errors."""

from __future__ import annotations

from pathlib import Path

from pxr import Usd, UsdValidation

from conftest import copy_samples
from csm_assets.formats import usd

USD_WALL = ("brick_wall.usda", "bricks_color.png", "bricks_height.png")


def wall_folder(tmp_path: Path) -> Path:
    """The sample USD wall and its textures copied into ``tmp_path/in``; returns the folder."""
    return copy_samples(tmp_path / "in", USD_WALL)


def edit(path: Path, change) -> Path:
    """Open the stage at ``path``, let ``change(stage)`` edit it, save it."""
    stage = Usd.Stage.Open(str(path))
    change(stage)
    stage.GetRootLayer().Save()
    return path


def validation_errors(path: Path) -> list[str]:
    """UsdValidation's errors on the stage at ``path`` (warnings left out)."""
    usd.register_shader_definitions()
    stage = Usd.Stage.Open(str(path))
    ctx = UsdValidation.ValidationContext(UsdValidation.ValidationRegistry().GetOrLoadAllValidators())
    return [f"{e.GetName()}: {e.GetMessage()}" for e in ctx.Validate(stage)
            if e.GetType() == UsdValidation.ValidationErrorType.Error]

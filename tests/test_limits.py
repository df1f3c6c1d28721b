"""Resource limits: defaults, environment overrides, refusals naming the file."""

from __future__ import annotations

import pytest

from csm_assets import limits
from csm_assets.errors import FormatError


def test_defaults_and_environment(monkeypatch):
    monkeypatch.delenv("CSM_ASSETS_MAX_VERTICES", raising=False)
    assert limits.limit("vertices") == limits.DEFAULTS["VERTICES"]
    monkeypatch.setenv("CSM_ASSETS_MAX_VERTICES", "1_000")
    assert limits.limit("VERTICES") == 1000
    limits.check("a.gltf", "vertices", 1000, "accessor 3")
    with pytest.raises(FormatError, match=r"a.gltf: accessor 3 declares 1,001 vertices.*CSM_ASSETS_MAX_VERTICES"):
        limits.check("a.gltf", "vertices", 1001, "accessor 3")


@pytest.mark.parametrize("raw", ["0", "-5", "lots", "1e9"])
def test_bad_environment_is_a_usage_error(monkeypatch, raw):
    monkeypatch.setenv("CSM_ASSETS_MAX_TEXELS", raw)
    with pytest.raises(ValueError, match="CSM_ASSETS_MAX_TEXELS"):
        limits.limit("texels")

"""``csm-assets blender install --blender EXE`` with an EXE that is no Blender: one line naming
it and what it is (exit 2), before anything runs."""

from __future__ import annotations

import pytest

from attack import assert_clean_error, run_cli


@pytest.mark.parametrize("kind, said", [("folder", "is a folder, not the Blender executable"),
                                        ("plain file", "is not executable"),
                                        ("nothing", "no such Blender executable")])
def test_an_exe_that_is_no_program_is_named_for_what_it_is(tmp_path, kind, said):
    """Was: a folder or a file without the executable bit was 'no such Blender executable'."""
    exe = tmp_path / "blender"
    if kind == "folder":
        exe.mkdir()
    elif kind == "plain file":
        exe.write_text("#!/bin/sh\n")
    error = assert_clean_error(run_cli("blender", "install", "--blender", exe, timeout=120), 2, exe)
    assert said in error, error

"""The real CLI in a subprocess with an action run at one point of a conversion: right after a
step map was made from the height texture's texels (``csm_assets.convert.maps.make_step_map``
returned), before anything is published. Races become deterministic: a texture replaced
while it is being converted, a conversion paused while it holds its output folder's lock."""

from __future__ import annotations

import subprocess
import sys

DRIVER = """
import os, runpy, sys
import csm_assets.convert.maps as maps
real = maps.make_step_map
def after_step_map(*args, **kwargs):
    made = real(*args, **kwargs)
    action = os.environ.get("CSM_TEST_AFTER_STEP_MAP")
    if action == "replace" and os.path.exists(os.environ["CSM_TEST_NEW"]):
        os.replace(os.environ["CSM_TEST_NEW"], os.environ["CSM_TEST_TEXTURE"])
    elif action == "pause":
        sys.stdout.write("paused\\n")
        sys.stdout.flush()
        sys.stdin.readline()
    return made
maps.make_step_map = after_step_map
sys.argv = ["csm-assets", *sys.argv[1:]]
runpy.run_module("csm_assets", run_name="__main__", alter_sys=True)
"""


def cli_command(*args) -> list[str]:
    """The command line of the CLI with the hook point (its action from the environment)."""
    return [sys.executable, "-c", DRIVER, *map(str, args)]


def replacing(texture, new, *args, env, timeout: float = 300) -> subprocess.CompletedProcess:
    """Run the CLI with ``args``; once the first step map is made, ``new`` replaces ``texture``
    (one rename, as an editor's save does)."""
    env = dict(env, CSM_TEST_AFTER_STEP_MAP="replace", CSM_TEST_NEW=str(new), CSM_TEST_TEXTURE=str(texture))
    return subprocess.run(cli_command(*args), env=env, capture_output=True, text=True, timeout=timeout)


def paused(*args, env) -> subprocess.Popen:
    """Start the CLI with ``args``; it prints ``paused`` once its first step map is made and
    waits for a line on its stdin before it goes on (holding its output folder's lock)."""
    env = dict(env, CSM_TEST_AFTER_STEP_MAP="pause")
    return subprocess.Popen(cli_command(*args), env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)

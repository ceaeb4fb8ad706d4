"""`use_compilation_cache`: the persistent cache of the notebooks and the command line. Each check
runs in a fresh process, since the cache is process configuration."""

import json
import os
import subprocess
import sys


_PROGRAM = """
import json, sys
import jax
from jax import monitoring

events = []
monitoring.register_event_listener(lambda name, **kw: events.append(name))
import bogie_jax as bj

if sys.argv[1] == "preset":  # a caller (a test session) set its own cache first
    jax.config.update("jax_compilation_cache_dir", sys.argv[2])
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 7.0)
directory = bj.use_compilation_cache(None if sys.argv[1] != "explicit" else sys.argv[2])
jax.block_until_ready(jax.jit(lambda x: jax.numpy.sin(x) @ x.T)(jax.numpy.ones((3, 3))))
from bogie_jax.runtime.program_store import program_store_directory

print(json.dumps({
    "directory": str(directory),
    "store": str(program_store_directory()),
    "min_compile_s": jax.config.jax_persistent_cache_min_compile_time_secs,
    "hits": events.count("/jax/compilation_cache/cache_hits"),
    "misses": events.count("/jax/compilation_cache/cache_misses"),
}))
"""


def _run(mode, directory, environ):
    env = {k: v for k, v in os.environ.items() if k != "BOGIE_JAX_CACHE_DIR"} | environ
    done = subprocess.run(
        [sys.executable, "-c", _PROGRAM, mode, str(directory)],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_second_process_reads_what_the_first_compiled(tmp_path):
    """`BOGIE_JAX_CACHE_DIR` is the default directory; every program is written (no minimum
    compile time), so a second identical process finds it there."""
    cache = tmp_path / "cache"
    environ = {"BOGIE_JAX_CACHE_DIR": str(cache)}
    first = _run("default", "-", environ)
    assert first["directory"] == str(cache) and first["store"] == str(cache / "programs")
    assert first["min_compile_s"] == 0.0
    assert first["misses"] >= 1 and first["hits"] == 0
    second = _run("default", "-", environ)
    assert second["hits"] >= 1 and second["misses"] == 0


def test_an_explicit_directory_wins_and_a_callers_cache_is_kept(tmp_path):
    explicit = _run("explicit", tmp_path / "mine", {"BOGIE_JAX_CACHE_DIR": str(tmp_path / "env")})
    assert explicit["directory"] == str(tmp_path / "mine")
    assert any((tmp_path / "mine").iterdir()) and not (tmp_path / "env").exists()
    preset = _run("preset", tmp_path / "session", {})
    assert preset["directory"] == str(tmp_path / "session")
    assert preset["min_compile_s"] == 7.0  # the caller's settings are left alone
    assert preset["store"] == str(tmp_path / "session" / "programs")

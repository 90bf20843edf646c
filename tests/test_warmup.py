"""``ikbench warmup`` (:mod:`ikbench.cli.commands.warmup`, :mod:`ikbench.methods.ours_lm.warmup`)
and where numba caches ikbench's kernels (:mod:`ikbench.runtime.numba_cache`).

The command's runs use a one-kernel group of a module written to a temporary folder, with
``NUMBA_CACHE_DIR`` there too (compiling ours-lm's real groups takes minutes: under
``-m slow``), each in a new process, so the second run finds numba's on-disk cache.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from ikbench.cli import main
from ikbench.runtime import numba_cache
from tests.conftest import REPO

KERNEL = textwrap.dedent("""
    from numba import njit

    @njit(cache=True)
    def twice(x):
        return 2.0 * x
    """)
#: A new process: the command with its groups replaced by one ("tiny", the kernel above).
DRIVER = textwrap.dedent("""
    import sys
    sys.path.insert(0, sys.argv[1])
    from ikbench.methods.ours_lm import warmup
    warmup._RUNS = {"tiny": lambda robot: (__import__("tiny_kernel").twice(1.0), None)[1]}
    warmup._MODULES = {"tiny": ("tiny_kernel",)}
    from ikbench.cli import main
    sys.exit(main(["warmup", "--groups", "tiny"]))
    """)


def _warmup(folder: Path, argv: list[str] | None = None) -> subprocess.CompletedProcess:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(folder / "numba"),
           "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    command = ([sys.executable, "-m", "ikbench.cli", "warmup", *argv] if argv is not None
               else [sys.executable, "-c", DRIVER, str(folder)])
    return subprocess.run(command, capture_output=True, text=True, env=env, timeout=900,
                          cwd=folder)


def test_warmup_compiles_once_with_a_line_per_group_then_says_already_compiled(tmp_path):
    (tmp_path / "tiny_kernel.py").write_text(KERNEL)
    first = _warmup(tmp_path)
    assert first.returncode == 0, first.stderr
    assert f"numba's cache: {tmp_path / 'numba'}" in first.stdout
    assert "tiny " in first.stdout and "compiled 1 kernel(s)" in first.stdout
    assert "one-time compile:" in first.stdout
    assert list((tmp_path / "numba").rglob("*.nbi")), "no index in NUMBA_CACHE_DIR"
    second = _warmup(tmp_path)
    assert second.returncode == 0, second.stderr
    assert "already compiled (1 from the cache)" in second.stdout
    assert "already compiled:" in second.stdout.splitlines()[-1]


def test_an_unknown_group_is_one_line_and_exit_2(capfd):
    assert main(["warmup", "--groups", "single-pose,nope"]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert err == ["ikbench: error: --groups: 'nope' is not one of single-pose, path, "
                   "path-search"]


@pytest.mark.slow
def test_warmup_of_the_single_pose_kernels_then_from_the_cache(tmp_path):
    first = _warmup(tmp_path, ["--groups", "single-pose"])
    assert first.returncode == 0, first.stderr
    assert "one-time compile:" in first.stdout
    second = _warmup(tmp_path, ["--groups", "single-pose"])
    assert "already compiled:" in second.stdout, second.stdout


def test_the_cache_is_beside_the_source_when_it_can_be_written(tmp_path, monkeypatch):
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    assert numba_cache.cache_dir(tmp_path) == (
        tmp_path / "__pycache__", "beside the source, its __pycache__ being writable")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "chosen"))
    folder, why = numba_cache.cache_dir(tmp_path)
    assert why == "NUMBA_CACHE_DIR" and folder.parent == tmp_path / "chosen"


def test_a_read_only_install_caches_in_numbas_user_folder_as_numba_does(tmp_path,
                                                                         monkeypatch):
    """The package folder not writable (monkeypatched: root writes read-only folders): the
    folder :func:`cache_dir` names is the one numba's own locator picks for a kernel there."""
    numba = pytest.importorskip("numba")
    from numba.core import caching

    source = tmp_path / "site-packages" / "somepkg"
    source.mkdir(parents=True)
    (source / "kernel_mod.py").write_text(KERNEL)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setattr(numba.config, "CACHE_DIR", "")
    monkeypatch.setattr(numba_cache, "writable", lambda folder: False)
    monkeypatch.setattr(caching.InTreeCacheLocator, "from_function",
                        classmethod(lambda cls, f, p: None))
    monkeypatch.syspath_prepend(str(source))
    import kernel_mod

    folder, why = numba_cache.cache_dir(source)
    assert why == "numba's per-user folder, the install being read-only"
    if sys.platform.startswith("linux"):
        assert folder.parent == tmp_path / "xdg" / "numba"
    assert Path(kernel_mod.twice._cache._cache_path) == folder

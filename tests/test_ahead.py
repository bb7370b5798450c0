"""The report's kernels compiled ahead in a second process, on a fresh Numba cache."""

import os
import subprocess
import sys

import numba
import pytest

pytestmark = pytest.mark.skipif(numba.config.DISABLE_JIT, reason="nothing is compiled")


def _python(code: str, cache) -> str:
    """What `code` prints in a fresh interpreter whose Numba cache is `cache`."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    return done.stdout.strip()


def test_a_second_process_compiles_the_late_kernels_into_a_fresh_cache(tmp_path):
    ahead = (
        "from zeroset._kernels._ahead import late_kernels_ahead, late_kernels_cached\n"
        "print(late_kernels_cached())\n"
        "with late_kernels_ahead() as process:\n"
        "    print(process.wait())\n"  # started, compiled and exited cleanly
        "print(late_kernels_cached())\n"
        "with late_kernels_ahead() as process:\n"
        "    print(process)"  # nothing left to compile: no process
    )
    assert _python(ahead, tmp_path).split() == ["False", "0", "True", "None"]
    # A later run loads the signatures it calls from the cache, compiling none of them.
    later = (
        "from zeroset._kernels import _ahead\n"
        "from zeroset.evaluate import compare_to_points\n"
        "from zeroset.orientation import orient_normals\n"
        "from zeroset.synthetic import sample_sphere\n"
        "sample = sample_sphere(2_000, rng=0)\n"
        "compare_to_points(sample.truth, sample.points)\n"
        "orient_normals(sample.points, sample.normals)\n"
        "for kernel in _ahead._late_kernels():\n"
        "    stats = kernel.stats\n"
        "    print(kernel.__name__, sum(stats.cache_hits.values()), "
        "sum(stats.cache_misses.values()))"
    )
    loaded = {
        name: (int(hits), int(misses))
        for name, hits, misses in (line.split() for line in _python(later, tmp_path).splitlines())
    }
    for name in ("_closest_face_rows", "_component_extremes", "_propagate_signs"):
        assert loaded[name] == (1, 0), name


@pytest.mark.slow
def test_the_first_demo_compiles_no_simplification_kernel_itself(tmp_path):
    # The demo starts the second process, which compiles the simplification's kernels
    # first; stage simplify waits for them rather than compiling them a second time.
    # Checked in the demo's own process: none compiled there (a miss), each loaded (a hit).
    demo = (
        "from zeroset import cli\n"
        "from zeroset._kernels import _ahead\n"
        "def counts():\n"
        "    for kernel in _ahead._simplify_kernels():\n"
        "        stats = kernel.stats\n"
        "        print(kernel.__name__, sum(stats.cache_hits.values()),"
        " sum(stats.cache_misses.values()))\n"
        f"cli.main(['demo', '--out', {str(tmp_path / 'demo')!r}, '--quiet'])\n"
        "counts()"
    )
    loaded = {
        name: (int(hits), int(misses))
        for name, hits, misses in (
            line.split() for line in _python(demo, tmp_path / "cache").splitlines()
        )
    }
    assert loaded == {name: (1, 0) for name in loaded} and len(loaded) == 7

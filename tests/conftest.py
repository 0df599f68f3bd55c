import contextlib

import numpy as np
import pytest

from rrrobot_gym import compiled, dynamics
from rrrobot_gym.simulation import initial_state


def pytest_configure(config):
    # A compiled stepper numba could not parallelise (parallel=True, but its prange loop not
    # transformed) or vectorise as asked warns once, when it compiles, and then runs correctly,
    # on one thread: bit-identity tests cannot see it. Fail the test that compiles it instead
    # (every run from an empty numba cache, as CI's, compiles every stepper it uses).
    if compiled.available():
        config.addinivalue_line("filterwarnings", "error::numba.NumbaPerformanceWarning")


def random_states(rng, n, max_tilt=0.6, max_rate=1.5):
    """n states with random attitude (tilt <= max_tilt), legs and speeds."""
    states = initial_state(n)
    theta = rng.uniform(-max_tilt, max_tilt, size=(n, 3))
    theta[:, 1] = rng.uniform(-np.pi, np.pi, size=n)  # heading is free
    states[:, dynamics.QUAT] = dynamics.quat_from_paper_angles(theta)
    states[:, dynamics.LEG_ANGLES] = rng.uniform(-0.8, 2.4, size=(n, 2))
    states[:, dynamics.BODY_RATE] = rng.uniform(-max_rate, max_rate, size=(n, 3))
    states[:, dynamics.LEG_RATES] = rng.uniform(-3 * max_rate, 3 * max_rate, size=(n, 2))
    states[:, 0:2] = rng.uniform(-1, 1, size=(n, 2))
    return states


ARRAY_TRANSCENDENTALS = ("sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "hypot", "sinh", "cosh", "tanh",
                         "exp", "exp2", "expm1", "log", "log2", "log10", "log1p", "cbrt")
"""numpy's functions whose array kernels depend on the CPU (SIMD: AVX-512's differ from AVX2's) and
may differ by an ulp from libm, which ``math`` and numba's compiled code call."""


@contextlib.contextmanager
def array_transcendentals_one_ulp_off():
    """numpy's :data:`ARRAY_TRANSCENDENTALS` returning results one ulp above their own: what another
    CPU's SIMD kernels may give. A quantity promised to the bit across backends or batch sizes that
    comes from one of them fails a comparison made inside this, on any machine. Run the compiled
    side first: numba must not compile while these are patched (it could not type them)."""
    originals = {name: getattr(np, name) for name in ARRAY_TRANSCENDENTALS}

    def nudged(ufunc):
        def call(*args, **kwargs):
            result = ufunc(*args, **kwargs)
            out = kwargs.get("out")
            target = (out[0] if isinstance(out, tuple) else out) if out is not None else None
            if target is not None:
                np.nextafter(target, np.inf, out=target)
                return result
            return np.nextafter(result, np.inf)

        return call

    try:
        for name, ufunc in originals.items():
            setattr(np, name, nudged(ufunc))
        assert np.sin(np.ones(3))[0] != originals["sin"](np.ones(3))[0]  # (the patch is live)
        yield
    finally:
        for name, ufunc in originals.items():
            setattr(np, name, ufunc)


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


@pytest.hookimpl(tryfirst=True)  # (before pytest-xdist reads the marks)
def pytest_collection_modifyitems(items):
    # Under pytest-xdist (pyproject's addopts), tests that share a module-scoped fixture of
    # these tests go to one worker, so the fixture (a training run, a search) is made once.
    for item in items:
        defs = getattr(item, "_fixtureinfo", None)
        shared = sorted(
            f"{fixture.baseid}::{name}"
            for name, fixtures in (defs.name2fixturedefs.items() if defs else ())
            for fixture in fixtures[-1:]
            if fixture.scope == "module" and fixture.baseid.startswith("tests")
        )
        if shared:
            item.add_marker(pytest.mark.xdist_group(shared[0]))

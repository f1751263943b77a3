"""Loading of the reference C++ libraries used as test and benchmark oracles.

``hpp_centroidal_dynamics`` (a cmeel wheel) links shared libraries under
``<site-packages>/cmeel.prefix/lib`` that the dynamic loader does not search; we preload
them with ``ctypes`` (RTLD_GLOBAL) and put the cmeel Python path on ``sys.path``.
Never a run-time dependency of Gecko.
"""

from __future__ import annotations

import ctypes
import importlib
import os
import sys
import sysconfig
from types import ModuleType

_PRELOAD = (
    "libboost_python311.so",
    "libeigenpy.so",
    "libcdd.so",
    "libCoinUtils.so",
    "libClp.so",
    "libqpOASES.so",
    "libhpp-centroidal-dynamics.so",
)

_cache: dict[str, ModuleType | str] = {}


def _cmeel_lib() -> str:
    return os.path.join(sysconfig.get_paths()["purelib"], "cmeel.prefix", "lib")


def load_centroidal_dynamics() -> ModuleType:
    """Import ``hpp_centroidal_dynamics`` or raise ImportError with a clear reason."""
    cached = _cache.get("hcd")
    if isinstance(cached, ModuleType):
        return cached
    if isinstance(cached, str):
        raise ImportError(cached)
    lib = _cmeel_lib()
    try:
        if not os.path.isdir(lib):
            raise ImportError(f"hpp-centroidal-dynamics oracle not installed (no {lib})")
        files = os.listdir(lib)
        for stem in _PRELOAD:
            matches = sorted(f for f in files if f.startswith(stem))
            if not matches:
                raise ImportError(f"hpp-centroidal-dynamics oracle: {stem} missing in {lib}")
            ctypes.CDLL(os.path.join(lib, matches[0]), mode=ctypes.RTLD_GLOBAL)
        pyver = f"python{sys.version_info.major}.{sys.version_info.minor}"
        pkg = os.path.join(lib, pyver, "site-packages")
        if pkg not in sys.path:
            sys.path.append(pkg)
        module = importlib.import_module("hpp_centroidal_dynamics")
    except (ImportError, OSError) as exc:
        reason = f"hpp-centroidal-dynamics oracle unavailable: {exc}"
        _cache["hcd"] = reason
        raise ImportError(reason) from exc
    _cache["hcd"] = module
    return module


class ReferenceEquilibrium:
    """Thin wrapper over the reference ``Equilibrium`` (one friction coefficient)."""

    def __init__(self, mass: float, n_rays: int = 4, algorithm: str = "PP") -> None:
        hcd = load_centroidal_dynamics()
        self._hcd = hcd
        self.mass = mass
        self.eq = hcd.Equilibrium("oracle", mass, n_rays, hcd.SolverLP.SOLVER_LP_QPOASES)
        self.alg = getattr(hcd.EquilibriumAlgorithm, f"EQUILIBRIUM_ALGORITHM_{algorithm}")

    def set_contacts(self, points, normals, mu: float) -> bool:  # type: ignore[no-untyped-def]
        """Set the contacts; False when it failed or when cdd was unstable, in which case
        the reference silently perturbs the contacts and answers another question."""
        import tempfile

        with tempfile.TemporaryFile() as err:
            saved = [os.dup(1), os.dup(2)]
            try:
                sys.stdout.flush()
                sys.stderr.flush()
                os.dup2(err.fileno(), 1)
                os.dup2(err.fileno(), 2)
                ok = bool(self.eq.setNewContacts(points, normals, mu, self.alg))
            finally:
                for fd, old in zip((1, 2), saved, strict=True):
                    os.dup2(old, fd)
                    os.close(old)
            err.seek(0)
            unstable = b"instability" in err.read()
        self.perturbed = unstable
        return ok and not unstable

    def set_contacts_fast(self, points, normals, mu: float) -> bool:  # type: ignore[no-untyped-def]
        """Set the contacts without capturing the diagnostics (for timing)."""
        return bool(self.eq.setNewContacts(points, normals, mu, self.alg))

    def com_polytope(self):  # type: ignore[no-untyped-def]
        """(A, b) with A @ c <= b for the COM, from the wrench polytope H w <= h."""
        import numpy as np

        H, h = self.eq.getPolytopeInequalities()
        D = np.zeros((6, 3))
        g = np.array([0.0, 0.0, -9.81])
        gx = np.array([[0, -g[2], g[1]], [g[2], 0, -g[0]], [-g[1], g[0], 0]])
        D[3:, :] = -self.mass * gx  # crossMatrix(-m g)
        d = np.zeros(6)
        d[:3] = self.mass * g
        return H @ D, h - H @ d

    def robustness(self, com):  # type: ignore[no-untyped-def]
        status, value = self.eq.computeEquilibriumRobustness(com)
        return status, float(value)

"""Shared test configuration: the hypothesis profile."""

from __future__ import annotations

from hypothesis import HealthCheck, settings

settings.register_profile(
    "gecko",
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
settings.load_profile("gecko")


def _preload_reference_oracle() -> None:
    """Import hpp-centroidal-dynamics (a test oracle) before anything imports Pinocchio.

    Both register boost.python converters for Eigen types; the oracle's module fails to
    initialise when Pinocchio's are already registered, while the other order works.
    """
    try:
        from bench._oracles import load_centroidal_dynamics

        load_centroidal_dynamics()
    except Exception:
        pass


_preload_reference_oracle()

# After the oracle: the live server's fixtures import the service, hence Pinocchio.
from tests.live_fixtures import gecko_url, live_results  # noqa: E402

__all__ = ["gecko_url", "live_results"]

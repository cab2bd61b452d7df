"""Blind campaign generators for testing ``vmt discover`` (issue 13, item 7).

Each generator is written apart from ``sim/`` and from the discovery engine
(and from each other), so the engine's tests cannot be tuned to them:

- :mod:`scenarios.blind.gen_a`: polygon/star pocket with a boss and bores,
  exact rigid-body chain with smooth (non-grid) errors, 19 effects.
- :mod:`scenarios.blind.gen_b`: blade plate (spline blade boss, pin arc,
  slot) on a table-type machine (X and Y carry the part), its own eq. 15
  projection for the truth, 18 effects.

``generate(effect, seed, **options) -> (ProbeLog, Truth)`` and ``effects()``
are the interface every generator offers.
"""

from .gen_a import effects, generate

__all__ = ["effects", "generate"]

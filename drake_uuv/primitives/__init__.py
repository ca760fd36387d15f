"""Small framework blocks used by the diagram builder."""

from drake_uuv.primitives.noise_hold import NoiseHold

__all__ = ["NoiseHold"]

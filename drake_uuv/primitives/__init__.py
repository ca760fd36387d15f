"""Small framework blocks used by the diagram builder."""

from drake_uuv.primitives.noise_hold import NoiseHold
from drake_uuv.primitives.random_input import declare_random_input, random_inputs

__all__ = ["NoiseHold", "declare_random_input", "random_inputs"]

"""Small framework blocks used by the diagram builder."""

from drake_uuv.primitives.noise_hold import NoiseHold
from drake_uuv.primitives.random_input import declare_random_input, random_inputs
from drake_uuv.primitives.signal import Signal

__all__ = ["NoiseHold", "Signal", "declare_random_input", "random_inputs"]

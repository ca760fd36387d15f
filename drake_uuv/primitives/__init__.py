"""Small pieces the systems and the builder share: random input ports, the signal type."""

from drake_uuv.primitives.random_input import (
    declare_random_input,
    export_random_inputs,
    random_inputs,
)
from drake_uuv.primitives.signal import Signal

__all__ = ["Signal", "declare_random_input", "export_random_inputs", "random_inputs"]

"""How an estimator accounts for the vehicle's own motion: two strategies, one interface.

The relative state ``Υ = X − X̄`` (vehicle less target) moves with the vehicle and with the
target. An estimator predicts it one of two ways (the scenario's
``estimator.vehicle_motion``):

- :class:`CommandedMotion` (``"commanded"``, the paper's): ``Υ̂(k+1|k) = A Υ̂(k|k) + B a_W(k)``
  with ``a_W = R u1`` the vehicle's commanded world acceleration (input ``u1_W``): exact for
  the paper's kinematic vehicle, which moves exactly as commanded. The stored prediction is
  the relative state itself.
- :class:`NavigatedMotion` (``"navigation"``): the vehicle's own state ``X = [p_WU, v_WU]`` is
  known (inputs ``p_WU_nav``, ``v_WU_nav``: the paper assumes it known; a real vehicle has
  its navigation), so the filter predicts the target alone, ``X̄(k+1|k) = A X̄(k|k)`` with
  ``X̄(k|k) = X(k) − Υ̂(k|k)``, and ``Υ̂(k+1|k) = X(k+1) − X̄(k+1|k)``: exact for any vehicle,
  whatever it did of its commands. The stored prediction is ``−X̄(k+1|k)``, the relative
  state less the vehicle's state; the prior of step k adds ``X(k)``.

Either way a prediction is ``A (x − offset) + B acceleration`` in the stored frame (``x −
offset`` is :meth:`stored`), and a prior is ``stored + offset``: :meth:`offset` is ``X(k)``
(navigation) or zero, and :meth:`acceleration` is ``a_W(k)`` (commanded) or zero. The
particle phase moves its particles with the same two numbers.
"""

import numpy as np
from pydrake.systems.framework import Context, InputPort, LeafSystem

_ZERO3 = np.zeros(3)
_ZERO6 = np.zeros(6)


class CommandedMotion:
    """The paper's prediction with the commanded acceleration; declares input ``u1_W`` (3)."""

    name = "commanded"

    def __init__(self, system: LeafSystem) -> None:
        self.acceleration_port = system.DeclareVectorInputPort("u1_W", 3)

    @property
    def state_ports(self) -> list[InputPort]:
        """The inputs the step's prior depends on (none: the prior is the stored state)."""
        return []

    def offset(self, context: Context) -> np.ndarray:
        return _ZERO6

    def acceleration(self, context: Context) -> np.ndarray:
        return self.acceleration_port.Eval(context)

    def prior(self, context: Context, stored: np.ndarray) -> np.ndarray:
        return stored

    def stored(self, context: Context, x: np.ndarray) -> np.ndarray:
        """``x − offset``: the relative state itself (``x − 0`` is ``x`` to the bit)."""
        return x


class NavigatedMotion:
    """The prediction of the target alone, the vehicle's state from its navigation; declares
    inputs ``p_WU_nav``, ``v_WU_nav`` (3 each)."""

    name = "navigation"

    def __init__(self, system: LeafSystem) -> None:
        self._ports = [system.DeclareVectorInputPort(name, 3) for name in ("p_WU_nav", "v_WU_nav")]

    @property
    def state_ports(self) -> list[InputPort]:
        return list(self._ports)

    def offset(self, context: Context) -> np.ndarray:
        """``X = [p_WU, v_WU]`` at this step."""
        p, v = (port.Eval(context) for port in self._ports)
        return np.concatenate([p, v])

    def acceleration(self, context: Context) -> np.ndarray:
        return _ZERO3

    def prior(self, context: Context, stored: np.ndarray) -> np.ndarray:
        return stored + self.offset(context)

    def stored(self, context: Context, x: np.ndarray) -> np.ndarray:
        """``x − offset``: a relative estimate in the frame the state stores."""
        return x - self.offset(context)


#: ``estimator.vehicle_motion`` → its strategy.
VEHICLE_MOTIONS: dict[str, type[CommandedMotion] | type[NavigatedMotion]] = {
    "commanded": CommandedMotion,
    "navigation": NavigatedMotion,
}

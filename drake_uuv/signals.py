"""The one table of the closed loop's signals: port names, loggers and ``log.npz`` keys.

Every signal is an output port of one system of the diagram, and its name is unique across
the diagram: the builder (:func:`drake_uuv.diagram.make_uuv_diagram`) connects every input
port to the output port of the same name, logs each logged signal with a logger named
``log_<name>``, and a run's log (``log.npz``) holds it under the same name, one row per step.
A slot's variant therefore reads whatever signals it needs by declaring input ports with
their names, and must produce the signals this table assigns to its system (the slot's
contract, checked when the diagram is built).

Frames (Drake's monogram notation): W world (z up), B the vehicle's body, U its body origin
(the midpoint of the two sonars), T the target. ``p_WU`` is the position of U in W, ``R_WB``
the attitude (body to world), ``x_TU`` the relative state ``[q, ϑ]`` of U from T in W, with
``q = p_WU − p_WT`` and ``ϑ = v_WU − v_WT`` (the paper's Υ). The plant's ``p_WU``, ``v_WU``,
``R_WB`` are the truth, read by the sonar, the navigation, the metrics and the figures; the
vehicle's own systems (estimator, attitude, tracking) read the navigation's ``*_nav``.
"""

from pydrake.systems.framework import System

from drake_uuv.primitives.signal import Signal

SIGNALS: tuple[Signal, ...] = (
    # The plant slot (system "uuv").
    Signal("p_WU", "uuv", (3,), "position of the vehicle's body origin U in W [m]"),
    Signal("v_WU", "uuv", (3,), "velocity of U in W [m/s]"),
    Signal("R_WB", "uuv", (3, 3), "attitude, body to world (row-major on the port)"),
    # The navigation slot (system "navigation"): what the vehicle believes of itself.
    Signal("p_WU_nav", "navigation", (3,), "navigated position of U in W [m]"),
    Signal("v_WU_nav", "navigation", (3,), "navigated velocity of U in W [m/s]"),
    Signal("R_WB_nav", "navigation", (3, 3), "navigated attitude, body to world"),
    # The target.
    Signal("p_WT", "target", (3,), "position of the target in W [m]"),
    Signal("v_WT", "target", (3,), "velocity of the target in W [m/s]"),
    # The dual sonar: its signals describe the ranges arriving at the tick (with a ping
    # offset or a latency, pings of earlier times), except b_W, the tick's.
    Signal("ranges", "sonar", (2,), "first range sample of sonars s1, s2 [m]; NaN: no return"),
    Signal("range_samples", "sonar", (-1,), "all f samples of s1, then of s2 [m]", logged=False),
    Signal("Y", "sonar", (), "the paper's measurement ½(d1² − d2²) [m²]"),
    Signal("m", "sonar", (), "mean of Y's noise [m²]"),
    Signal("Gamma", "sonar", (), "variance Γ of Y's noise [m⁴]"),
    Signal("b_W", "sonar", (3,), "sonar baseline R_WB b in W, the paper's q_s [m]"),
    Signal(
        "sonar_status",
        "sonar",
        (2,),
        "per sonar, of the range arriving: valid, dropped, out of beam, out of range, no arrival",
        integer=True,
    ),  # fmt: skip
    Signal("multipath", "sonar", (2,), "ground truth: each return's multipath excess [m]"),
    Signal("ping_time", "sonar", (2,), "when each arriving range's ping was sent [s]; NaN: none"),
    Signal(
        "p_TS_W",
        "sonar",
        (6,),
        "ground truth: each arriving range's sonar (s1's 3, s2's 3) from the target at its "
        "ping, W [m]; NaN: none",
    ),
    # The estimator slot.
    Signal("x_TU_hat", "estimator", (6,), "filtered estimate x(k|k) = [q̂, ϑ̂] [m, m/s]"),
    Signal("P_TU", "estimator", (6, 6), "covariance P(k|k) of x_TU_hat"),
    Signal("x_TU_prior", "estimator", (6,), "prediction x(k|k−1)", logged=False),
    Signal("P_TU_prior", "estimator", (6, 6), "covariance P(k|k−1)", logged=False),
    Signal(
        "measurement_status",
        "estimator",
        (),
        "valid, dropped, out of beam, out of range, gated",
        integer=True,
    ),  # fmt: skip
    Signal("nis", "estimator", (), "normalised innovation squared of the update; NaN: none"),
    # The attitude slot.
    Signal(
        "u2_W", "attitude_generator", (3,), "the paper's u2: angular velocity command, W [rad/s]"
    ),  # fmt: skip
    Signal("R_WB_plan", "attitude_generator", (2, 3, 3), "planned R(k+1), R(k+2)", logged=False),
    # The tracking slot.
    Signal("u1_B", "tracking_controller", (3,), "the paper's u1: acceleration command, B [m/s²]"),
    Signal(
        "u1_W", "tracking_controller", (3,), "u1 in W, R_WB_nav u1_B: the filter's input [m/s²]"
    ),  # fmt: skip
)

#: Signals by name.
SIGNAL_BY_NAME: dict[str, Signal] = {s.name: s for s in SIGNALS}


def logged_signals(systems: dict[str, System]) -> list[Signal]:
    """The signals a run of these systems logs: :data:`SIGNALS` that are logged, then the
    ``extra_signals`` a system declares (e.g. a real vehicle's thrusts), a tuple of
    :class:`~drake_uuv.primitives.signal.Signal` naming its own output ports."""
    signals = [s for s in SIGNALS if s.logged]
    for system in systems.values():
        signals += [s for s in getattr(system, "extra_signals", ()) if s.logged]
    return signals


def check_contract(name: str, system: System, variant: str, batch_size: int = 1) -> None:
    """Raises ``ValueError`` if ``system`` (named ``name`` in the diagram, built for the
    variant ``variant``) lacks an output the table assigns to it, or has the wrong size: a
    signal's size per run times ``batch_size``, the runs the system steps at once."""
    for signal in SIGNALS:
        if signal.system != name:
            continue
        if not system.HasOutputPort(signal.name):
            raise ValueError(
                f"{name} ({variant}): has no output port {signal.name!r} ({signal.meaning})"
            )
        size = system.GetOutputPort(signal.name).size()
        if signal.size > 0 and size != signal.size * batch_size:
            runs = "" if batch_size == 1 else f" ({signal.size} for each of {batch_size} runs)"
            raise ValueError(
                f"{name} ({variant}): output port {signal.name!r} has size {size}, "
                f"expected {signal.size * batch_size}{runs}"
            )

"""The terminal text of a study: a few lines from its summary."""

from collections.abc import Callable
from typing import Any


def format_summary(summary: dict[str, Any]) -> str:
    """A few lines for the terminal."""

    def number(value: float | None, fmt: str = ".4g") -> str:
        return "—" if value is None else format(value, fmt)

    def interval(key: str) -> str:
        low, high = summary[key]
        return f"[{number(low)}, {number(high)}]"

    return "\n".join(
        [
            f"{summary['runs']} runs, seeds {summary['first_seed']}.."
            f"{summary['first_seed'] + summary['runs'] - 1}, k ≥ {summary['steady_state_start']}:",
            f"  position RMSE {number(summary['position_rmse'])} m "
            f"{interval('position_rmse_ci95')}",
            f"  velocity RMSE {number(summary['velocity_rmse'])} m/s "
            f"{interval('velocity_rmse_ci95')}",
            f"  tracking RMSE {number(summary['tracking_rmse'])} m "
            f"{interval('tracking_rmse_ci95')}",
            f"  mean NEES {number(summary['nees_mean'])} {interval('nees_mean_ci95')} (6 if "
            "consistent)",
            f"  diverged {summary['diverged_fraction']:.1%}, tracking bounded "
            f"{summary['tracking_bounded_fraction']:.1%}" + _warned(summary),
            *_bound_lines(summary, number),
        ]
    )


def _warned(summary: dict[str, Any]) -> str:
    """The share of runs that warned of a broken assumption (none in an older summary)."""
    if "warned_fraction" not in summary:
        return ""
    return f", warned {summary['warned_fraction']:.1%} (drake-uuv run --seed S says why)"


def _bound_lines(summary: dict[str, Any], number: Callable[..., str]) -> list[str]:
    """The PCRLB lines of :func:`format_summary` (none when the summary has no bound)."""
    lines = []
    for part, unit in (("position", "m"), ("velocity", "m/s")):
        if f"{part}_rmse_over_pcrlb" not in summary:
            continue
        line = (
            f"  {part} PCRLB {number(summary[f'pcrlb_{part}_rmse'])} {unit}: RMSE / PCRLB "
            f"{number(summary[f'{part}_rmse_over_pcrlb'], '.3f')}"
        )
        if f"{part}_rmse_over_per_run_pcrlb" in summary:
            line += (
                f", / per-run bound {number(summary[f'pcrlb_per_run_{part}_rmse'])} "
                f"{number(summary[f'{part}_rmse_over_per_run_pcrlb'], '.3f')}"
            )
        if f"kf_riccati_{part}_rmse" in summary:
            line += f"; paper-KF Riccati {number(summary[f'kf_riccati_{part}_rmse'])}"
        lines.append(line)
    return lines

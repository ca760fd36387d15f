"""Named groups of comparison variants, and how ``drake-uuv compare`` finds them.

The package holds no study: the groups (the paper's claims, the vehicle, the estimators'
regimes, ...) and the results page's sections live in a *studies folder*, by default the
``studies/`` folder of the repository checkout this package was imported from
(:func:`default_studies_folder`; ``pip install -e .`` keeps it beside ``drake_uuv/``). A
studies folder is a Python package that is not installed: ``DIR/__init__.py`` defines

    GROUPS: list[Group]   # in the order ``--group list`` shows them

and may import its sibling modules relatively (``from .vehicle import VEHICLE``).
:func:`load_studies` imports it from its path under a private module name (``studies_`` and
a digest of the path), without adding anything to ``sys.path``; loading the same folder again
returns the module already loaded.

A :class:`Group` lists its variants explicitly (a new estimator or attitude variant joins a
group only when someone adds it there), says in one line what it measures, and whether it is
one of the paper's: ``drake-uuv compare`` without ``--group`` runs those.
"""

import hashlib
import importlib.util
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

from drake_uuv.studies.comparison import Variant, compare
from drake_uuv.studies.study import MonteCarloError, StudyResult

# The --group value that lists the groups instead of naming one.
LIST = "list"


@dataclass(frozen=True)
class Group:
    """A named group of variants: ``drake-uuv compare --group NAME``."""

    name: str
    # One line for ``--group list``: what the group measures.
    description: str
    variants: Callable[[], list[Variant]]
    # One of the paper's claims: run by ``drake-uuv compare`` when no --group is given.
    paper: bool = False


def default_studies_folder() -> Path:
    """``studies/`` beside the imported ``drake_uuv`` package: the checkout's, when the
    package is installed editable from a repository (it need not exist otherwise)."""
    # parents[0] is drake_uuv/studies, parents[1] drake_uuv, parents[2] the checkout.
    return Path(__file__).resolve().parents[2] / "studies"


def _no_groups(folder: Path, why: str) -> MonteCarloError:
    return MonteCarloError(f"--studies: no study groups in {folder} ({why})")


def load_studies(folder: Path) -> ModuleType:
    """The studies folder ``folder`` imported as a package from its path (see the module).

    Raises :class:`MonteCarloError` naming the path if it has no ``__init__.py``.
    """
    folder = Path(folder).resolve()
    init = folder / "__init__.py"
    if not init.is_file():
        raise _no_groups(folder, "no __init__.py there; pass --studies DIR")
    name = "studies_" + hashlib.sha256(str(folder).encode()).hexdigest()[:12]
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(
        name, init, submodule_search_locations=[str(folder)]
    )
    module = importlib.util.module_from_spec(spec)
    # Registered before it runs, so that its relative imports find their parent package.
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        for loaded in [m for m in sys.modules if m == name or m.startswith(f"{name}.")]:
            del sys.modules[loaded]
        raise
    return module


def load_groups(folder: Path) -> dict[str, Group]:
    """The groups of a studies folder by name, in its order; :class:`MonteCarloError` naming
    the path if it defines none, or a group that is not a :class:`Group` or repeats a name."""
    module = load_studies(folder)
    groups = getattr(module, "GROUPS", None)
    where = Path(folder).resolve()
    if not groups:
        raise _no_groups(where, "its __init__.py defines no GROUPS")
    found: dict[str, Group] = {}
    for group in groups:
        if not isinstance(group, Group):
            raise _no_groups(where, f"GROUPS holds {group!r}, not a drake_uuv.studies.Group")
        if group.name in found:
            raise _no_groups(where, f"GROUPS names {group.name!r} twice")
        if group.name == LIST:
            raise _no_groups(
                where, f"GROUPS names {LIST!r}, which --group reserves for listing the groups"
            )
        found[group.name] = group
    return found


def select_groups(groups: Mapping[str, Group], names: Sequence[str] | None) -> list[Group]:
    """The named groups, each once, in the order named; the paper's groups if none are named.

    Raises :class:`MonteCarloError` on an unknown name (listing the known ones).
    """
    if not names:
        chosen = [group for group in groups.values() if group.paper]
        if not chosen:
            raise MonteCarloError(
                f"--group: no group is marked as the paper's; name one (known: {', '.join(groups)})"
            )
        return chosen
    for name in names:
        if name not in groups:
            raise MonteCarloError(f"--group: unknown group {name!r} (known: {', '.join(groups)})")
    return [groups[name] for name in dict.fromkeys(names)]


def group_variants(groups: Sequence[Group]) -> list[Variant]:
    """Every variant of the groups, group by group."""
    return [variant for group in groups for variant in group.variants()]


def compare_groups(
    groups: Sequence[Group], out_dir: Path, runs: int, **options: Any
) -> list[tuple[Variant, StudyResult]]:
    """:func:`~drake_uuv.studies.comparison.compare` of the groups' variants, named by their
    groups in ``compare.md``; ``options`` as for it."""
    names = [group.name for group in groups]
    return compare(group_variants(groups), out_dir, runs, groups=names, **options)


def format_group_list(groups: Mapping[str, Group], runs: int) -> str:
    """``--group list``: each group's name, variants, runs at ``runs`` per variant, and line."""
    variants = {name: group.variants() for name, group in groups.items()}
    counts = {name: len(rows) for name, rows in variants.items()}
    total = {name: sum(row.runs(runs) for row in rows) for name, rows in variants.items()}
    width = max(len("group"), *(len(name) + 1 for name in groups))
    lines = [f"{'group':<{width}}  variants  {'runs':>6}  description"]
    for name, group in groups.items():
        label = name + ("*" if group.paper else "")
        lines.append(f"{label:<{width}}  {counts[name]:>8}  {total[name]:>6}  {group.description}")
    lines.append(f"runs at --runs {runs}; * the paper's groups, run when no --group is given")
    return "\n".join(lines)

"""The controllers a study can name: the built-in ones, installed packages' entry points and the study's own
`[controllers]` table (`trials.controllers.plugins`), one spelling each.

These names are the levels of a study's `Controller` factor, the arms a sealed key maps to and the
`controller` column of outcomes.csv; `designs` and `analysis` get them from here as data.
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import Any

from trials.controllers.checked import OFFLINE_PLAN_LIMIT_S, CheckedController
from trials.controllers.plugins import BUILT_IN, PluginError, Source, build_plugin, entry_points, study_sources

NAVIGAN_R = "NaviGAN-R"
LATTICE = "Lattice"
SOCIAL_FORCE = "SocialForce"
ORCA = "ORCA"
NAV_STACK = "NavStack"
#: The controller of a run whose study has no Controller factor.
DEFAULT = NAVIGAN_R
#: The paper's A/B study: NaviGAN-R against the lattice planner (`trials design --ab`).
AB_PRESET = (NAVIGAN_R, LATTICE)


@dataclass(frozen=True)
class ControllerOptions:
    """What a `trials run` command line and the study can set on the controllers."""

    weights: str | None = None  # NaviGAN-R's checkpoint (default: the shipped all-scenes weights)
    #: The study's `[controllers]` table (name, "module:factory") and the folder its modules are also found in.
    study: tuple[tuple[str, str], ...] = ()
    folder: str | None = None
    #: The longest a plan may take (None: the caller times plans itself, as the live loop does).
    plan_limit_s: float | None = OFFLINE_PLAN_LIMIT_S


#: Each built-in controller's class, imported only when it is built (NaviGAN-R loads PyTorch, the lattice its compiled
#: search); NaviGAN-R alone takes an option, its weights.
BUILT_INS: dict[str, str] = {
    NAVIGAN_R: "trials.controllers.navigan_r:NaviganRController",
    LATTICE: "trials.controllers.lattice:LatticeController",
    SOCIAL_FORCE: "trials.controllers.social_force:SocialForceController",
    ORCA: "trials.controllers.orca:OrcaController",
    NAV_STACK: "trials.controllers.nav_stack:NavStackController",
}
#: The built-in controllers' names.
NAMES: tuple[str, ...] = tuple(BUILT_INS)


def _built_in(name: str, options: ControllerOptions) -> Any:
    module, _, cls = BUILT_INS[name].partition(":")
    made = getattr(importlib.import_module(module), cls)
    return made(options.weights) if name == NAVIGAN_R else made()


def _toolkit() -> str:
    try:
        return f"navtrials {version('navtrials')}"
    except PackageNotFoundError:
        return "navtrials"


def sources(study: Mapping[str, str] | None = None) -> dict[str, Source]:
    """Every controller a study may name, by name: built-in, then installed packages', then the study's table.

    Raises:
        PluginError: two sources offer one name (the message names both).
    """
    found = {name: Source(name, BUILT_IN, reference, _toolkit()) for name, reference in BUILT_INS.items()}
    for more in (entry_points(), study_sources(study or {})):
        for name, source in more.items():
            if name in found:
                raise PluginError(f"two controllers are called {name!r}: {found[name].describe()} and {source.describe()}; "
                                  "rename one")
            found[name] = source
    return found


def names(study: Mapping[str, str] | None = None) -> tuple[str, ...]:
    """Every controller name a study may use (`sources`' order)."""
    return tuple(sources(study))


def build(name: str, options: ControllerOptions = ControllerOptions()) -> Any:
    """The controller called `name`, built with `options` and checked (`CheckedController`).

    Raises:
        StudyError: no controller has that name (the message lists the known ones), or a plug-in that fails to load.
    """
    known = sources(dict(options.study))
    source = known.get(name)
    if source is None:
        raise PluginError(f"no controller is called {name!r} (known: {', '.join(known)})")
    inner = _built_in(name, options) if source.kind == BUILT_IN else build_plugin(source, Path(options.folder) if options.folder else None)
    return CheckedController(inner, name, source, options.plan_limit_s)

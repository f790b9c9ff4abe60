"""The controllers a study can name: one spelling each, mapped to the factory that builds it.

These names are the levels of a study's `Controller` factor, the arms a sealed key maps to and the
`controller` column of outcomes.csv; `designs` and `analysis` get them from here as data.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from trials.controllers.base import Controller
from trials.errors import StudyError

NAVIGAN_R = "NaviGAN-R"
LATTICE = "Lattice"
#: The controller of a run whose study has no Controller factor.
DEFAULT = NAVIGAN_R


@dataclass(frozen=True)
class ControllerOptions:
    """What a `trials run` command line can set on the controllers."""

    weights: str | None = None  # NaviGAN-R's checkpoint (default: the shipped all-scenes weights)


# Each factory imports its controller when called: NaviGAN-R loads PyTorch, the lattice its compiled search.
def _navigan_r(options: ControllerOptions) -> Controller:
    from trials.controllers.navigan_r import NaviganRController

    return NaviganRController(options.weights)


def _lattice(options: ControllerOptions) -> Controller:
    from trials.controllers.lattice import LatticeController

    return LatticeController()


FACTORIES: dict[str, Callable[[ControllerOptions], Controller]] = {NAVIGAN_R: _navigan_r, LATTICE: _lattice}
#: Every controller name, in the order the A/B preset lists them.
NAMES: tuple[str, ...] = tuple(FACTORIES)


def build(name: str, options: ControllerOptions = ControllerOptions()) -> Controller:
    """The controller called `name`, built with `options`.

    Raises:
        StudyError: no controller has that name (the message lists the known ones).
    """
    factory = FACTORIES.get(name)
    if factory is None:
        raise StudyError(f"no controller is called {name!r} (known: {', '.join(NAMES)})")
    return factory(options)

"""`trials controllers`: every controller a study can name, where each comes from, and (`--check`) whether each builds
and plans."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from trials import option_types as types

if TYPE_CHECKING:
    from trials.controllers.base import Controller


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "controllers",
        help="list the controllers a study can name as arms: built-in, from installed packages, from a study.toml",
        description=(
            "List every controller by the name a study gives it (a Controller level, a --arms item) and where it comes "
            "from: built into navtrials, an installed package's entry point (group navtrials.controllers), or a "
            "study.toml's [controllers] table (NAME = \"module:factory\"). Nothing is imported unless --check is given. "
            "A blinded study's own controllers are sealed and are not named."
        ),
    )
    parser.add_argument("--study", type=types.folder, metavar="DIR", help="also the controllers of this study's [controllers] table")
    parser.add_argument("--check", action="store_true",
                        help="build each controller and plan once for a robot meeting one person; exit 2 when any fails")
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from trials.controllers import registry
    from trials.controllers.nav_stack import is_nav_stack
    from trials.controllers.plugins import study_controllers
    from trials.errors import USER_ERRORS
    from trials.study import SEALED_CONTROLLERS, StudyFolder

    folder = StudyFolder(args.study) if args.study is not None else None
    own = study_controllers(folder, blind=False) if folder is not None else {}
    options = registry.ControllerOptions(study=tuple(own.items()), folder=str(folder.root) if folder is not None else None)
    sources = registry.sources(own)
    width = max(len(name) for name in sources)
    failed = 0
    for name, source in sources.items():
        line = f"{name:<{width}}  {source.describe()}"
        if args.check:
            try:
                built = registry.build(name, options)
                line += ("  live only: the robot's stack plans (trials run --robot URI)" if is_nav_stack(built)
                         else f"  plans ({_check(built):.3f} s)")
            except USER_ERRORS as exc:
                failed += 1
                line += f"  FAILS: {exc}"
        print(line)
    if folder is not None and folder.path(SEALED_CONTROLLERS).exists():
        print(f"The study's own controllers are sealed ({SEALED_CONTROLLERS}); `trials run` builds them.")
    return 2 if failed else 0


def _check(controller: Controller) -> float:
    """Run `controller` once for a robot 5 m from a person walking toward it; the seconds it took.

    Raises:
        ControllerFault: it raised or answered outside the interface (one line).
    """
    import time

    import numpy as np

    from robot_logs.physical import STEP_S, T_OBS
    from trials.controllers.base import Observation
    from trials.controllers.checked import ControllerFault

    walking = np.column_stack([5.0 + 1.2 * STEP_S * np.arange(T_OBS)[::-1], np.full(T_OBS, 0.3)])[None]
    observation = Observation(0.0, np.zeros(3), np.zeros(2), np.array([10.0, 0.0]), np.zeros((T_OBS, 2)), (1,), walking)
    began = time.perf_counter()
    try:
        controller.reset(0)
        controller.plan(observation)
        controller.end("goal")
    except ControllerFault:
        raise
    except Exception as exc:  # a plug-in may raise anything: it is reported in one line, never as a traceback
        raise ControllerFault(f"it raised {type(exc).__name__}: {exc}".splitlines()[0]) from None
    return time.perf_counter() - began

"""Controllers from outside the toolkit: installed packages' entry points and a study's `[controllers]` table.

An installed package offers a controller with an entry point in the group `navtrials.controllers`, its name the
controller's name and its value `module:factory`; a study names one in study.toml's `[controllers]` table
(`Name = "module:factory"`), the module found on the Python path or in the study folder. The factory takes no
arguments and returns an object with `plan(observation)` (`trials.controllers.base`); finding names imports nothing,
so `trials controllers` lists every controller quickly and a broken plug-in fails only when its study needs it.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import sys
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from trials.errors import StudyError
from trials.study import SEALED_CONTROLLERS, SPEC, StudyFolder, study_table

#: The entry point group an installed package names its controllers in.
ENTRY_POINT_GROUP = "navtrials.controllers"
#: Where a controller came from.
BUILT_IN, ENTRY_POINT, STUDY_TABLE = "built-in", "entry point", "study.toml [controllers]"
#: study.toml's table of the study's own controllers.
TABLE = "controllers"
#: Characters a controller's name may not hold: it is a plan.csv cell and a `--arms` list item.
_FORBIDDEN = set(',"\n\r\t')


class PluginError(StudyError):
    """A controller plug-in that cannot be found, imported or built; the message names it and where it came from."""


@dataclass(frozen=True)
class Source:
    """Where a controller comes from: its kind, its `module:factory` reference and, for a package, its name and version."""

    name: str
    kind: str
    reference: str
    distribution: str = ""

    def describe(self) -> str:
        """E.g. `entry point lab-planner 1.2 (lab_planner:make)` or `study.toml [controllers] (planner:make)`."""
        package = f" {self.distribution}" if self.distribution else ""
        return f"{self.kind}{package} ({self.reference})"


def check_name(name: str, where: str) -> None:
    """Refuse a controller name a plan.csv cell or an `--arms` list could not hold."""
    if not name.strip() or name != name.strip() or _FORBIDDEN & set(name):
        raise PluginError(f"{where}: controller name {name!r} must be non-empty, without surrounding spaces, commas, "
                          "quotes, tabs or line breaks")


def check_reference(reference: object, where: str) -> str:
    """A `module:factory` reference, or a one-line error naming `where`."""
    module, _, attribute = reference.partition(":") if isinstance(reference, str) else ("", "", "")
    if not (module and attribute and all(part.isidentifier() for part in module.split(".") + attribute.split("."))):
        raise PluginError(f"{where}: expected \"module:factory\" (e.g. \"my_planner:make_controller\"), got {reference!r}")
    return str(reference)


def read_table(spec: Path) -> dict[str, str]:
    """A study.toml's `[controllers]` table ({} when the file or the table is missing), every entry checked.

    Raises:
        StudyError: unreadable TOML, a bad name or a reference that is not "module:factory", naming the file and key.
    """
    table = study_table(spec, TABLE) or {}
    for name, reference in table.items():
        check_name(name, f"{spec} [{TABLE}]")
        check_reference(reference, f"{spec} [{TABLE}] {name}")
    return dict(table)


def study_controllers(folder: StudyFolder, blind: bool) -> dict[str, str]:
    """The study's own controllers: study.toml's `[controllers]`, or in a blinded study the sealed copy of it (a public
    file never names a blinded study's controllers)."""
    return read_table(folder.path(SEALED_CONTROLLERS if blind else SPEC))


def entry_points() -> dict[str, Source]:
    """Every installed package's controllers, by name; a name offered twice is refused, naming both packages."""
    found: dict[str, Source] = {}
    for point in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        dist = point.dist
        package = f"{dist.metadata['Name']} {dist.version}" if dist is not None else ""
        source = Source(point.name, ENTRY_POINT, point.value, package)
        if point.name in found and found[point.name] != source:
            raise PluginError(f"two installed packages offer a controller called {point.name!r}: "
                              f"{found[point.name].describe()} and {source.describe()}; uninstall one")
        check_name(point.name, f"entry point of {package or point.value}")
        found[point.name] = source
    return found


def study_sources(table: Mapping[str, str]) -> dict[str, Source]:
    """A study's `[controllers]` table as sources."""
    return {name: Source(name, STUDY_TABLE, reference) for name, reference in table.items()}


@contextmanager
def _study_path(folder: Path | None) -> Iterator[None]:
    """The study folder first on the import path while a study's own module is imported."""
    if folder is None:
        yield
        return
    entry = str(folder.resolve())
    sys.path.insert(0, entry)
    try:
        yield
    finally:
        with suppress(ValueError):
            sys.path.remove(entry)


def load_factory(source: Source, folder: Path | None = None) -> Callable[[], Any]:
    """Import `source`'s factory; a study's own module is also looked for in `folder`.

    Raises:
        PluginError: the module does not import or has no such callable; the message names the controller, its source
            and the exception's first line.
    """
    module_name, _, attribute = source.reference.partition(":")
    where = f"controller {source.name!r} from {source.describe()}"
    try:
        with _study_path(folder if source.kind == STUDY_TABLE else None):
            target: Any = importlib.import_module(module_name)
    except Exception as exc:  # a plug-in's import may raise anything; the run must not start on it
        raise PluginError(f"{where}: cannot import {module_name!r}: {type(exc).__name__}: {_first_line(exc)}") from None
    for part in attribute.split("."):
        if not hasattr(target, part):
            raise PluginError(f"{where}: module {module_name!r} has no {attribute!r}")
        target = getattr(target, part)
    if not callable(target):
        raise PluginError(f"{where}: {source.reference} is not callable")
    return target


def build_plugin(source: Source, folder: Path | None = None) -> Any:
    """Call `source`'s factory and check that what it built can plan.

    Raises:
        PluginError: the import, the factory call or the built object fails (one line naming the controller).
    """
    factory = load_factory(source, folder)
    where = f"controller {source.name!r} from {source.describe()}"
    try:
        built = factory()
    except Exception as exc:
        raise PluginError(f"{where}: its factory raised {type(exc).__name__}: {_first_line(exc)}") from None
    if not callable(getattr(built, "plan", None)):
        raise PluginError(f"{where}: its factory returned {type(built).__name__}, which has no plan(observation) method")
    return built


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else "(no message)"

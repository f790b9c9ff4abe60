"""The trials package's exception type, and the one list of every package's user-error types."""

from analysis.errors import AnalysisError
from designs.errors import DesignError
from navigan.errors import NaviganError
from robot_logs.errors import LogError
from trials.lattice.errors import LatticeError


class StudyError(ValueError):
    """A study folder or command request that cannot be served; the message says what and where."""


class RunAborted(StudyError):
    """A live run stopped before its own ending (e-stop, stale sensors, a signal, the middleware lost); the message says
    why and where its log went, and names no controller. The row stays pending."""


class EStopped(RunAborted):
    """A live run stopped, or kept from starting, by an e-stop (the console's, or the robot's e-stop topic): the whole
    `trials run` session ends there, and no later row starts."""


class DiskFullError(StudyError):
    """A file could not be written for want of space; every later write would fail too, so work stops."""


#: Exception types that mean "the user asked for something wrong", never a bug: the CLI prints them
#: as one `error:` line with exit code 2, and `trials run` reports them from its workers without a traceback.
USER_ERRORS: tuple[type[Exception], ...] = (DesignError, StudyError, LogError, NaviganError, AnalysisError, LatticeError)

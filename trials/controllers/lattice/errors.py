"""The one exception type of the lattice planner."""

from trials.errors import StudyError


class LatticeError(StudyError):
    """A malformed SBPL file or an impossible planning request; the message names the file, line or field."""

"""The one exception type of the lattice planner."""


class LatticeError(ValueError):
    """A malformed SBPL file or an impossible planning request; the message names the file, line or field."""

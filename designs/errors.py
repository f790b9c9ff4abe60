"""The one exception type of the designs package."""


class DesignError(ValueError):
    """A study spec, model or design request that cannot be built; the message says what and where."""

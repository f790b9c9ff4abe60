"""The one exception type of the trials package."""


class StudyError(ValueError):
    """A study folder or command request that cannot be served; the message says what and where."""

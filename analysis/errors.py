"""The one exception type of the analysis package."""


class AnalysisError(ValueError):
    """Results that cannot be scored or reported as asked; the message says what and where."""

"""The one exception type of the navigan package."""


class NaviganError(ValueError):
    """Data, checkpoints or requests NaviGAN cannot use; the message says what and where."""

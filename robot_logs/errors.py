"""The one exception type of the robot_logs package."""


class LogError(ValueError):
    """A log file or request that cannot be served; the message names the file and what is wrong."""

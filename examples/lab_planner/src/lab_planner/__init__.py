"""A navtrials controller plug-in: `make_controller` is the factory the entry point names."""

from lab_planner.gap_keeper import GapKeeper


def make_controller() -> GapKeeper:
    """The controller navtrials builds once per worker and drives for every run of its arm."""
    return GapKeeper()


__all__ = ["GapKeeper", "make_controller"]

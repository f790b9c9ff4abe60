"""The playback episode protocols by name, and the default: a module without imports, so the CLI can
offer them without loading torch (what each protocol selects: `navigan.playback.episodes`)."""

PRESENT, OBSERVED = "present", "observed"
PROTOCOLS = (PRESENT, OBSERVED)
#: The default: its human row lies nearer the paper's Table I than PRESENT's (docs/playback.md).
DEFAULT_PROTOCOL = OBSERVED

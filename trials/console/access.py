"""console/access.json, the console's keys (owner-only): the experimenter's token, which opens the run
sheet, and the key that signs participants' links and the session cookies. Made once per study and
kept, so printed QR codes and open pages stay valid when the console restarts.

A participant's link for run `code` carries an HMAC of the code under that key: it cannot be guessed
from the code, and opens that run's questionnaire only.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import secrets
from dataclasses import dataclass

from trials.atomic import write_files
from trials.errors import StudyError
from trials.study import CONSOLE_ACCESS, StudyFolder

FORMAT = "navtrials.console-access/1"
#: Bytes of randomness in the experimenter's token and the signing key.
TOKEN_BYTES = 24
#: Hex characters of a participant link's HMAC (96 bits).
LINK_CHARS = 24


@dataclass(frozen=True)
class ConsoleAccess:
    """The experimenter's token and the signing key of one study's console."""

    experimenter_token: str
    secret_key: str

    def participant_token(self, code: str) -> str:
        """The token in run `code`'s questionnaire link."""
        digest = hmac.new(self.secret_key.encode(), f"participant:{code}".encode(), hashlib.sha256).hexdigest()
        return digest[:LINK_CHARS]

    def run_of(self, token: str, codes: list[str]) -> str | None:
        """The run whose questionnaire link carries `token`, if any."""
        return next((code for code in codes if hmac.compare_digest(self.participant_token(code), token)), None)

    def is_experimenter(self, token: str) -> bool:
        return hmac.compare_digest(self.experimenter_token.encode(), token.encode())


def console_access(folder: StudyFolder) -> ConsoleAccess:
    """The study's console keys, made (console/ 0700, the file 0600) the first time."""
    path = folder.path(CONSOLE_ACCESS)
    if not path.exists():
        access = ConsoleAccess(secrets.token_urlsafe(TOKEN_BYTES), secrets.token_hex(TOKEN_BYTES))
        path.parent.mkdir(mode=0o700, exist_ok=True)
        path.parent.chmod(0o700)
        record = {"format": FORMAT, "experimenter_token": access.experimenter_token, "secret_key": access.secret_key}
        write_files({path: (json.dumps(record, indent=1) + "\n").encode()}, private=[path])
        return access
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        if data.get("format") != FORMAT:
            raise ValueError(f"its format must be {FORMAT!r}")
        return ConsoleAccess(str(data["experimenter_token"]), str(data["secret_key"]))
    except (ValueError, KeyError, AttributeError) as exc:
        raise StudyError(f"{path} is damaged ({exc}); delete it to make new keys (old links stop working)") from None

"""One base exception for everything a user can get wrong, with narrow subclasses.

Every error carries *where* it happened (a block path, a field, a value) so that the CLI can
print one line and exit with status 2.
"""

from __future__ import annotations

import re


class AzeeError(Exception):
    """Base of every error ``azee_mj`` raises for bad input."""


class ScoreError(AzeeError):
    """An invalid score: ``path`` is the dotted block path, ``field`` the offending key."""

    def __init__(self, message: str, path: str = "", field: str = ""):
        super().__init__(message)
        self.path = path
        self.field = field


class ModelError(AzeeError):
    """A signer model that does not fit its :class:`~azee_mj.sites.SignerMap`."""


class InputFileError(AzeeError):
    """A file that cannot be read or has the wrong contents (path in the message)."""


class OutputError(AzeeError):
    """An output path that cannot or must not be written (path in the message)."""


#: Values longer than this many characters are shortened in messages.
MAX_SHOWN = 80

# C0 / C1 controls, DEL, and the bidirectional and line-separator marks a terminal obeys.
_CONTROL = re.compile(
    "[\x00-\x1f\x7f-\x9f\u061c\u200e\u200f\u2028\u2029\u202a-\u202e\u2066-\u2069]"
)
#: Longest message printed [characters].
MAX_MESSAGE = 1000
#: Longest unbroken run of characters a printed message keeps (a long path still fits).
MAX_RUN = 300
_LONG_RUN = re.compile(rf"[^\s:;,']{{{MAX_SHOWN + 1},}}")
_VERY_LONG_RUN = re.compile(rf"[^\s:;,']{{{MAX_RUN + 1},}}")


def printable(text: str) -> str:
    """``text`` with control characters and terminal escapes written as ``\\xNN`` /
    ``\\uNNNN`` (a message stays one line and cannot drive the terminal)."""

    def esc(m: re.Match) -> str:
        c = ord(m.group())
        return f"\\x{c:02x}" if c < 0x100 else f"\\u{c:04x}"

    return _CONTROL.sub(esc, text)


def shorten(text: str, limit: int = MAX_SHOWN) -> str:
    """``text`` cut to ``limit`` characters with an ellipsis."""
    return text if len(text) <= limit else text[: limit - 1] + "…"


def tidy(message: str) -> str:
    """A message safe to print: controls escaped, words longer than :data:`MAX_SHOWN`
    characters shortened, and the whole cut at :data:`MAX_MESSAGE`."""
    message = _LONG_RUN.sub(lambda m: shorten(m.group()), printable(message))
    return shorten(message, MAX_MESSAGE)


def one_line(message: str) -> str:
    """A message as the command line prints it: controls escaped, runs of more than
    :data:`MAX_RUN` characters without a break shortened (a 1 MB name is not printed
    whole; a path is), and the whole cut at :data:`MAX_MESSAGE`."""
    message = _VERY_LONG_RUN.sub(lambda m: shorten(m.group(), MAX_SHOWN), printable(message))
    return shorten(message, MAX_MESSAGE)

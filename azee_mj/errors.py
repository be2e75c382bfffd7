"""One base exception for everything a user can get wrong, with narrow subclasses.

Every error carries *where* it happened (a block path, a field, a value) so that the CLI can
print one line and exit with status 2.
"""

from __future__ import annotations


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

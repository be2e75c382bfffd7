"""The one error of the text front end: where in the text, where in the expression tree."""

from __future__ import annotations

from azee_mj.errors import AzeeError


class ExpressionError(AzeeError):
    """A bad ``.azee`` expression.

    The message reads ``FILE:LINE:COL: PATH: problem; what is valid``. ``file`` is the file
    name (``<text>`` for a string, ``<-e>`` on the command line), ``line`` and ``col`` are
    1-based (0 when no position applies), ``path`` is the chain of rules and labels from the
    root (``:info-about'info:tens-units'tens``) or ``syntax`` for a parse error, and
    ``problem`` the message without its location.
    """

    def __init__(
        self,
        problem: str,
        *,
        file: str = "<text>",
        line: int = 0,
        col: int = 0,
        path: str = "syntax",
    ):
        where = f"{file}:{line}:{col}" if line else file
        super().__init__(f"{where}: {path}: {problem}" if path else f"{where}: {problem}")
        self.problem = problem
        self.file = file
        self.line = line
        self.col = col
        self.path = path

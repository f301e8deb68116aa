"""One error type for everything a user can fix; the CLI prints it as one line."""


class EfficientEQAError(RuntimeError):
    """A failure with a known cause. ``fix`` names what the user should do."""

    def __init__(self, message: str, fix: str | None = None) -> None:
        super().__init__(message)
        self.fix = fix

    def __str__(self) -> str:
        base = super().__str__()
        return f"{base} ({self.fix})" if self.fix else base


def first_line(error: BaseException, limit: int = 200) -> str:
    """What a library's ``error`` says, fit for a one-line message: the first line of its text
    (a size mismatch or a model loader's message spans many), cut to ``limit`` characters, or
    its type's name where it says nothing."""
    lines = str(error).strip().splitlines()
    text = lines[0].strip() if lines else type(error).__name__
    return text if len(text) <= limit else text[:limit - 3] + "..."

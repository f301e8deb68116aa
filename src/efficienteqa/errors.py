"""One error type for everything a user can fix; the CLI prints it as one line."""


class EfficientEQAError(RuntimeError):
    """A failure with a known cause. ``fix`` names what the user should do."""

    def __init__(self, message: str, fix: str | None = None) -> None:
        super().__init__(message)
        self.fix = fix

    def __str__(self) -> str:
        base = super().__str__()
        return f"{base} ({self.fix})" if self.fix else base

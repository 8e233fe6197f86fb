"""What every binding of an outside device shares (``hil fly --can``/``--uart``): the device's
first failure is reported once, the binding closes, and the emulator keeps running without it."""

from __future__ import annotations

from collections.abc import Callable

__all__ = ["DeviceBinding"]


class DeviceBinding:
    """Mixin: set ``closed``, ``error``, ``log`` and implement :meth:`describe` and
    :meth:`_close_device`."""

    closed: bool
    error: str | None
    log: Callable[[str], None]

    def describe(self) -> str:  # pragma: no cover - abstract
        raise NotImplementedError

    def _close_device(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _fail(self, exc: BaseException) -> None:
        if self.error is None:
            self.error = f"{type(exc).__name__}: {exc}"
            self.log(f"hil: {self.describe()} failed ({self.error}); closed, the emulator keeps "
                     "running without it")
        self.close()

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            try:
                self._close_device()
            except Exception:  # noqa: BLE001 - a dying device may fail in any way
                pass

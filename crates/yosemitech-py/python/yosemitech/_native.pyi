"""Types of the native module (``yosemitech._native``)."""

from os import PathLike
from types import TracebackType
from typing import Dict, List, Optional, Sequence, Type, Union

Value = Union[float, int, str]

def sensors() -> List[dict]:
    """Every loaded sensor: name, title, model, model_code, default_address,
    baud, and commands (name, read, trigger, role, fixed_address, register, count, fields with name, unit,
    min, max)."""

def load_spec(path: Union[str, "PathLike[str]"]) -> List[str]:
    """Loads a spec file or directory, replacing built-in sensors of the same
    name; returns the names of its sensors. Raises SpecError."""

class Bus:
    """A serial port (``/dev/ttyUSB0``) or an RTU-over-TCP gateway
    (``tcp://host:port``); the GIL is released while the port is driven."""

    def __init__(self, port: str, baud: Optional[int] = None, timeout: float = 1.0, retries: int = 2) -> None: ...
    def read(self, sensor: str, command: str, address: int) -> Dict[str, Value]:
        """The fields of ``command``'s reply, by name. A write raises
        RequestError: this package reads only."""
    def scan(self, addresses: Optional[Sequence[int]] = None) -> List[dict]:
        """What answers at each address (1-247 by default), identified as
        ``yosemitech scan`` does: address, sensor, candidates, serial_number,
        model_code, models, hardware, software, manual_software, reason."""

class Simulator:
    """A probe simulated from its spec, served over TCP on loopback."""

    def __init__(self, sensor: str, address: Optional[int] = None) -> None: ...
    @property
    def url(self) -> str:
        """``tcp://127.0.0.1:PORT``, for :class:`Bus`."""
    def values(self, command: str) -> Dict[str, Value]:
        """The fields ``command`` holds now: what a read returns."""
    def stop(self) -> None: ...
    def __enter__(self) -> "Simulator": ...
    def __exit__(
        self,
        exc_type: Optional[Type[BaseException]],
        exc: Optional[BaseException],
        tb: Optional[TracebackType],
    ) -> bool: ...

class YosemitechError(Exception): ...
class SpecError(YosemitechError): ...
class UnknownError(YosemitechError): ...
class RequestError(YosemitechError): ...
class BusError(YosemitechError): ...
class NoReply(BusError): ...
class CrcError(BusError): ...
class ExceptionReply(BusError):
    """args: (message, Modbus exception code)."""
class DecodeError(YosemitechError): ...

"""Yosemitech water-quality probes over Modbus RTU, from Python.

Every sensor of the spec (``sensors()``), a read of any command
(``Bus.read``), the probes on a bus identified as
``yosemitech scan`` does (``Bus.scan``), and a probe simulated from its spec
(``Simulator``) so that code written for a probe runs without one. The
work is done by the Rust library the ``yosemitech`` tools share; this
package is its Python face, not a second implementation.

Example::

    import yosemitech
    sensor = yosemitech.sensors()[0]
    with yosemitech.Simulator(sensor["name"]) as sim:
        bus = yosemitech.Bus(sim.url)
        print(bus.scan([sensor["default_address"]]))
"""

from ._native import (
    Bus,
    BusError,
    CrcError,
    DecodeError,
    ExceptionReply,
    NoReply,
    RequestError,
    Simulator,
    SpecError,
    UnknownError,
    YosemitechError,
    load_spec,
    sensors,
)

__all__ = [
    "Bus",
    "BusError",
    "CrcError",
    "DecodeError",
    "ExceptionReply",
    "NoReply",
    "RequestError",
    "Simulator",
    "SpecError",
    "UnknownError",
    "YosemitechError",
    "load_spec",
    "sensors",
]

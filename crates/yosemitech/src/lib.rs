//! Typed, allocation-free Modbus RTU codecs, device handles and procedures for Yosemitech water-quality sensors, generated from the vendor manuals.

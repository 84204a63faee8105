"""marinebench: simulation benchmarks for marine-vehicle observers and controllers."""

__version__ = "0.1.0"

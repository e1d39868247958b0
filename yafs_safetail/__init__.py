"""yafs-safetail: SafeTail learned redundant edge dispatch on a YAFS-compatible simulator."""

__version__ = "0.1.0"

"""Small YAFS scenarios shared by the core tests."""

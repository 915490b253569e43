"""The Zenoh hub."""

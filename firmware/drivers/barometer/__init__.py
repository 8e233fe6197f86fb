"""Barometer drivers."""

"""Magnetometer drivers."""

"""Stress-controlled (servo) walls (Luding & Herrmann LH 1.2)."""

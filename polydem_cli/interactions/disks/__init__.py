"""Disk contact family (Luding & Herrmann): the hysteretic cohesive spring law and its kernel."""

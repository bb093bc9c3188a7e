"""Controllers: families that read the state of a step and steer or stop the run (interactions/protocol.py)."""

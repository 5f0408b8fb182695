"""AgNav host companion: link, perception, planners and the world simulator."""

__version__ = "0.1.0"

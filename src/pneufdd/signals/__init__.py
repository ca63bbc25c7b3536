"""pneufdd.signals (see README for the package map)."""

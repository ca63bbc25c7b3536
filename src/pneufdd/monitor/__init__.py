"""pneufdd.monitor (see README for the package map)."""

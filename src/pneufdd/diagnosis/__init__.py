"""pneufdd.diagnosis (see README for the package map)."""

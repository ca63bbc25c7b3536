"""pneufdd.features (see README for the package map)."""

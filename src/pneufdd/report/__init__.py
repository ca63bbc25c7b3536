"""pneufdd.report (see README for the package map)."""

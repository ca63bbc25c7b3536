"""Advise: the thin, typed ``pneufdd`` command-line interface over the library."""

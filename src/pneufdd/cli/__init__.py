"""Advise: the thin, typed ``pneufdd`` command-line interface over the library.

May import: every other package; nothing imports it. The library never imports
``rich``; only this package does.
"""

"""Web: the dashboard over the fault history (``pneufdd serve``, ``docs/dashboard.md``).

Starlette + uvicorn, Jinja2 templates, charts built by :mod:`pneufdd.report.plotly_figures`
and drawn with the plotly.js of the installed ``plotly`` package; live updates by
server-sent events. Nothing is fetched from outside at run time.

May import: :mod:`pneufdd.report`, :mod:`pneufdd.monitor` and the layers below; not cli.
"""

from __future__ import annotations

"""The report's tables: the paper's Tables 1 to 6 and the claims table, from the tidy metrics
table, beside the paper's numbers.

One module per concern; this package imports none of them (a rule's inputs are the modules its
script imports, so each script imports only the modules it uses):

- :mod:`freqbrdf.report.tables.paper`: the paper's numbers (``config/paper_results.yaml``);
- :mod:`freqbrdf.report.tables.tidy`: queries on the tidy metrics table (`freqbrdf.layout.METRICS`);
- :mod:`freqbrdf.report.tables.display`: how the cells show numbers and methods;
- :mod:`freqbrdf.report.tables.tables`: the tables, DataFrames of display strings;
- :mod:`freqbrdf.report.tables.claims`: the paper's claims, checked on a run;
- :mod:`freqbrdf.report.tables.render`: Markdown, LaTeX and HTML renderers;
- :mod:`freqbrdf.report.tables.summary`: what rule tables writes, each table with its caption,
  and the report's landing summary.
"""

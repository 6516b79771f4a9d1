"""The thesis' numbers reproduced: the validation cases (``cases``), their runner (``run``:
``make validate`` or ``python -m validation.run``) and the report (``report``: the tables of
``validation/README.md``, ``summary.csv`` and the figures)."""

"""The Trino functions lakegate translates, one module per page of Trino's function reference
(docs/src/main/sphinx/functions/*.md); pages.py lists them and fills lakegate.dialect.registry.
"""

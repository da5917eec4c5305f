"""The differential run over Trino 476's own function tests (`python3 dev.py corpus`): the SQL of
every QueryAssertions call in the compiled tests (io.trino:trino-main:476:jar:tests), answered by
lakegate and by the real Trino, and judged as the conformance differential judges."""

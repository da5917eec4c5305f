"""Name resolution: the Relations mixin of the Analyzer, which resolves every table and
column against the schema (CTEs, derived tables, VALUES, UNNEST, joins, correlated subqueries).
"""

from __future__ import annotations

from sqlglot import exp

from lakegate.dialect import trino_types as tt
from lakegate.dialect.named_windows import resolve_named_windows, window_keys
from lakegate.dialect.trino_types import TType
from lakegate.dialect.type_rules import UNORDERABLE, NameScope, OutCol, Source, ttype
from lakegate.dialect.with_ties import rank_filter, rank_keys, with_ties


def same_value(a: exp.Expression, b: exp.Expression) -> bool:
    """The same expression, columns compared by what they resolved to."""
    if isinstance(a, exp.Column) and isinstance(b, exp.Column) and a._meta and b._meta:
        return a.meta.get("ref") == b.meta.get("ref") and a.meta.get("sql") == b.meta.get("sql")
    return a == b


def _using_value(source: Source, col: OutCol, common: TType) -> str:
    """The DuckDB SQL of one side's USING column, cast to the join column's type."""
    quoted = ".".join('"' + part.replace('"', '""') + '"' for part in (source.qualifier, col[1]))
    sql = source.using.get(col[1].lower(), quoted)
    return sql if col[2] == common else f"CAST({sql} AS {tt.duckdb_type(common)})"


def same_field_or_inside(ref: tuple, key: exp.Expression) -> bool:
    """Whether a column reference (qualifier, column, field path) is GROUP BY key `key`, a column,
    or one of its fields."""
    if not (isinstance(key, exp.Column) and key._meta and key.meta.get("ref") is not None):
        return False
    qualifier, column, path = key.meta["ref"]
    return ref[:2] == (qualifier, column) and ref[2][: len(path)] == path


def ident_name(ident: exp.Expression) -> str:
    """Trino's output name for an identifier: as written, quoted or not (names are matched without
    regard to case)."""
    return ident.name


_GROUPING_ELEMENT = {exp.Rollup: "ROLLUP", exp.Cube: "CUBE", exp.GroupingSets: "GROUPING SETS"}


def grouping_keys(element: exp.Expression) -> list[exp.Expression]:
    """The expressions a ROLLUP, CUBE or GROUPING SETS element groups by (sets and their parentheses
    unwrapped; `()` holds none)."""
    keys = []
    for item in element.expressions:
        if isinstance(item, (exp.Tuple, exp.Paren)):
            keys.extend(
                grouping_keys(exp.Tuple(expressions=[item.this]))
                if isinstance(item, exp.Paren)
                else grouping_keys(item)
            )
        elif isinstance(item, (exp.Rollup, exp.Cube, exp.GroupingSets)):
            keys.extend(grouping_keys(item))
        else:
            keys.append(item)
    return keys


def nested_order(t: TType) -> bool:
    """An array or row whose elements are themselves arrays, maps or rows: the ordering of
    transforms.ordered_comparison checks one level of NULL elements only."""
    members = [t.element] if t.base == "array" else [f for _, f in t.args] if t.base == "row" else []
    return any(m.base in ("array", "map", "row") for m in members)


class Relations:
    """Name resolution: queries, WITH, SELECT, set operations, VALUES, relations, UNNEST, joins,
    GROUP BY, ORDER BY and the columns and fields names refer to (a mixin of analyzer.Analyzer)."""

    # --- queries --------------------------------------------------------------------------------
    def query(self, node: exp.Expression, outer: NameScope | None) -> list[OutCol]:
        """Analyze a query (SELECT, set operation, VALUES, parenthesized query); its output columns."""
        if isinstance(node, exp.Subquery) and not node.alias:
            cols = self.query(node.this, outer)
            self._modifiers(node, cols, outer)
            return cols
        if isinstance(node, exp.Select):
            return self.select(node, outer)
        if isinstance(node, exp.SetOperation):
            return self.set_operation(node, outer)
        if isinstance(node, exp.Values):
            return self.values(node, outer)
        self.unsupported(f"statement {node.key.upper()}", node)

    def _with(self, node: exp.Expression, outer: NameScope | None) -> NameScope:
        scope = NameScope(outer=outer)
        with_ = node.args.get("with_")
        if with_ is not None:
            if with_.args.get("recursive"):
                self.unsupported("WITH RECURSIVE", with_)
            for cte in with_.expressions:
                cols = self.query(cte.this, scope)
                names = [c.name for c in cte.args["alias"].columns] if cte.args["alias"].columns else None
                if names:
                    if len(names) != len(cols):
                        self.fail(
                            f"WITH query name {cte.alias} specifies {len(names)} column names, "
                            f"but the query has {len(cols)}",
                            cte,
                            "MISMATCHED_COLUMN_ALIASES",
                        )
                    cols = [(ident_name(i), ident_name(i), c[2]) for i, c in zip(cte.args["alias"].columns, cols)]
                scope.ctes[cte.alias.lower()] = cols
        return scope

    def select(self, node: exp.Select, outer: NameScope | None) -> list[OutCol]:
        for key in (
            "qualify",
            "laterals",
            "connect",
            "pivots",
            "prewhere",
            "sample",
            "distribute",
            "sort",
            "cluster",
            "into",
            "locks",
            "settings",
            "format",
            "options",
            "match",
            "exclude",
            "for_",
        ):
            if node.args.get(key):
                self.unsupported(
                    {"sample": "TABLESAMPLE"}.get(key, key.upper().rstrip("_")),
                    node.args[key] if isinstance(node.args[key], exp.Expression) else node,
                )
        definitions = resolve_named_windows(node, self.sql, self.fail)
        if with_ties(node.args.get("limit")) and node.args.get("order") is not None:
            node.meta["rank_keys"] = rank_keys(node)
        scope = self._with(node, outer)
        from_ = node.args.get("from_")
        if from_ is not None:
            self.relation(from_.this, scope)
        for join in node.args.get("joins") or []:
            self.join(join, scope)
        where = node.args.get("where")
        if where is not None:
            self.condition(where.this, scope, "WHERE")
        outputs = self.projection(node, scope)
        group = node.args.get("group")
        if group is not None:
            self.group(group, node, scope)
        having = node.args.get("having")
        if having is not None:
            self.condition(having.this, scope, "HAVING")
        node.meta["window_keys"] = [key for d in definitions for key in window_keys(d)]
        for key in node.meta["window_keys"]:  # Trino analyzes every WINDOW definition, used or not
            self.expr(key, scope, {})
        distinct = node.args.get("distinct")
        if distinct is not None and distinct.args.get("on"):
            self.unsupported("DISTINCT ON", distinct)
        node.meta["outputs"] = outputs
        self._modifiers(node, outputs, scope)
        self.check_grouping(node, scope)
        self.check_time_tz_keys(node)
        if distinct is not None and node.args.get("order") is not None:
            self.check_distinct_order(node)
        return outputs

    def _modifiers(self, node: exp.Expression, outputs: list[OutCol], scope: NameScope | None) -> None:
        order = node.args.get("order")
        if order is not None:
            order_scope = scope if scope is not None else NameScope()
            order_scope = NameScope(order_scope.sources, order_scope.outer, order_scope.ctes, outputs)
            for ordered in order.expressions:
                self.order_item(ordered, outputs, order_scope)
        for key in ("limit", "offset"):
            clause = node.args.get(key)
            if clause is None:
                continue
            if isinstance(clause, exp.Fetch):
                count = clause.args.get("count")
                options = clause.args.get("limit_options")  # where sqlglot keeps WITH TIES now
                if clause.args.get("percent") or options and options.args.get("percent"):
                    self.unsupported("FETCH FIRST ... PERCENT", clause)
                if isinstance(count, exp.Literal) and count.name == "0":
                    message = "FETCH FIRST row count must be positive (actual value: 0)"
                    self.fail(message, clause, "NUMERIC_VALUE_OUT_OF_RANGE")
                if with_ties(clause):
                    self.fetch_with_ties(node, clause, scope)
            else:
                count = clause.expression
            if count is not None and not (
                isinstance(count, exp.Literal) and not count.is_string and count.name.isdigit()
            ):
                if not (isinstance(count, exp.Var) and count.name.upper() == "ALL"):
                    self.fail(f"{key.upper()} must be a non-negative integer literal", clause, "TYPE_MISMATCH")

    def fetch_with_ties(self, node: exp.Expression, fetch: exp.Fetch, scope: NameScope | None) -> None:
        """FETCH FIRST n ROWS WITH TIES becomes QUALIFY rank() ... <= offset + n (dialect/with_ties.py)."""
        order = node.args.get("order")
        if order is None:
            self.fail("FETCH FIRST WITH TIES clause requires ORDER BY", fetch, "MISSING_ORDER_BY")
        keys = node.meta.get("rank_keys") if isinstance(node, exp.Select) else None
        if keys is None or node.args.get("distinct") is not None:
            of = "SELECT DISTINCT" if keys is not None else "a set operation or parenthesized query"
            self.unsupported(f"FETCH FIRST ... WITH TIES of {of}", fetch)
        if any(o.meta.get("key") for o in order.expressions) or any(k.find(exp.Window) for k in keys):
            self.unsupported("FETCH FIRST ... WITH TIES ordered by an array, a row or a window function", fetch)
        count, offset = fetch.args.get("count"), node.args.get("offset")
        rows = int(count.name) if isinstance(count, exp.Literal) and count.name.isdigit() else 1
        if offset is not None and isinstance(offset.expression, exp.Literal) and offset.expression.name.isdigit():
            rows += int(offset.expression.name)
        condition = rank_filter(keys, rows)
        node.set("qualify", exp.Qualify(this=condition))
        self.condition(condition, scope, "FETCH FIRST WITH TIES")
        node.set("limit", None)

    def order_item(self, ordered: exp.Ordered, outputs: list[OutCol], scope: NameScope) -> None:
        target = ordered.this
        if isinstance(target, exp.Literal) and not target.is_string:
            index = int(target.name) if target.name.isdigit() else 0
            if not 1 <= index <= len(outputs):
                self.fail(f"ORDER BY position {target.name} is not in select list", target, "INVALID_COLUMN_REFERENCE")
            t = outputs[index - 1][2]
        else:
            t = self.expr(target, scope, {})
        if t.base in UNORDERABLE:
            self.fail(f"Type {t} is not orderable, and therefore cannot be used in ORDER BY", target, "TYPE_MISMATCH")
        if t.base in ("array", "row"):  # Trino fails when sorting reaches a NULL element: checked per key
            if nested_order(t) or isinstance(target, exp.Literal):
                self.unsupported(f"ORDER BY {'position of ' if isinstance(target, exp.Literal) else ''}{t}", target)
            ordered.meta["key"] = t

    def group(self, group: exp.Group, select: exp.Select, scope: NameScope) -> None:
        if group.args.get("all"):
            self.unsupported("GROUP BY ALL", group)
        for key in ("grouping_sets", "cube", "rollup", "totals"):
            for item in group.args.get(key) or []:
                self.unsupported(
                    f"GROUP BY {key.upper().replace('_', ' ')}", item if isinstance(item, exp.Expression) else group
                )
        for item in group.expressions:
            if isinstance(item, (exp.Rollup, exp.Cube, exp.GroupingSets)):
                for key in grouping_keys(item):
                    if isinstance(key, exp.Literal) and not key.is_string:
                        self.unsupported(f"a column position in {_GROUPING_ELEMENT[type(item)]}", key)
                    self.expr(key, scope, {})
                continue
            if isinstance(item, exp.Literal) and not item.is_string:
                index = int(item.name) if item.name.isdigit() else 0
                if not 1 <= index <= len(select.expressions):
                    self.fail(f"GROUP BY position {item.name} is not in select list", item, "INVALID_COLUMN_REFERENCE")
                target = select.expressions[index - 1].unalias()
                if isinstance(target, exp.Column) and not isinstance(target.this, exp.Star):
                    # the column itself, as Trino groups by it: DuckDB groups a position by the written select
                    # item (a cast of the column), and then refuses the column in a correlated subquery
                    item = item.replace(target.copy())
                    self.expr(item, scope, {})
                continue
            self.expr(item, scope, {})

    def condition(self, node: exp.Expression, scope: NameScope, clause: str) -> None:
        t = self.expr(node, scope, {})
        if t.base not in ("boolean", "unknown"):
            self.fail(f"{clause} clause must evaluate to a boolean: actual type {t}", node, "TYPE_MISMATCH")

    def set_operation(self, node: exp.SetOperation, outer: NameScope | None) -> list[OutCol]:
        if node.args.get("by_name"):  # Trino matches the common columns by name; DuckDB's BY NAME keeps all
            self.unsupported(f"{node.key.upper()} CORRESPONDING", node)
        scope = self._with(node, outer)
        branches = []
        for branch in (node.this, node.expression):
            branches.append(self.query(branch, scope))
        left, right = branches
        if len(left) != len(right):
            self.fail(
                f"{node.key.upper()} query has different number of fields: {len(left)}, {len(right)}",
                node,
                "TYPE_MISMATCH",
            )
        outputs = []
        for index, (a, b) in enumerate(zip(left, right)):
            common = tt.common_super_type(a[2], b[2])
            if common is None:
                self.fail(
                    f"column {index + 1} in {node.key.upper()} query has incompatible types: {a[2]}, {b[2]}",
                    node,
                    "TYPE_MISMATCH",
                )
            self.zoned_cast_in_utc_only(a[2], b[2], node, f"{node.key.upper()} of {a[2]} and {b[2]}")
            outputs.append((a[0], a[1], common))
        if node.args.get("distinct") or isinstance(node, (exp.Intersect, exp.Except)):
            for col in outputs:
                if col[2].base == "time_tz":  # DuckDB would tell apart one instant in two offsets
                    self.unsupported(f"{node.key.upper()} of {col[2]}", node)
                if col[2].base in UNORDERABLE[:3]:
                    self.fail(
                        f"Type {col[2]} is not comparable, and therefore cannot be used in {node.key.upper()}",
                        node,
                        "TYPE_MISMATCH",
                    )
        node.meta["outputs"] = outputs
        self._modifiers(node, outputs, NameScope(outer=scope))
        return outputs

    def values(self, node: exp.Values, outer: NameScope | None) -> list[OutCol]:
        scope = NameScope(outer=outer)
        rows = []
        for row in node.expressions:
            cells = row.expressions if isinstance(row, exp.Tuple) else [row]
            if len(cells) == 1 and (_is_row_call(cells[0]) or self.expr(cells[0], scope, {}).base == "row"):
                cells = self._row_fields(row, cells[0])  # ROW(...)'s fields, never typed as a row value
            rows.append([self.expr(c, scope, {}) for c in cells])
        width = len(rows[0])
        if any(len(r) != width for r in rows):
            self.fail("Values rows have mismatched sizes", node, "TYPE_MISMATCH")
        types = []
        for index in range(width):
            common = tt.common_super_type_of([r[index] for r in rows])
            if common is None:
                self.fail(
                    f"Values rows have mismatched types: {', '.join(str(r[index]) for r in rows)}",
                    node,
                    "TYPE_MISMATCH",
                )
            types.append(common)
        node.meta["types"] = types
        return [(None, f"_col{i}", t) for i, t in enumerate(types)]

    def _row_fields(self, row: exp.Expression, cell: exp.Expression) -> list[exp.Expression]:
        """A VALUES item of a row type is one column per field in Trino (StatementAnalyzer.visitValues);
        written as ROW(...) it becomes those fields, any other row-typed item is refused."""
        if not _is_row_call(cell):
            self.unsupported("a VALUES item of a row type that is not ROW(...) (Trino makes each field a column)", cell)
        fields = list(cell.expressions)
        (row if isinstance(row, exp.Tuple) else cell).replace(exp.Tuple(expressions=fields))
        return fields

    # --- FROM -----------------------------------------------------------------------------------
    def relation(self, node: exp.Expression, scope: NameScope, lateral_scope: NameScope | None = None) -> None:
        """Add the relation `node` (table, derived table, VALUES, UNNEST) to `scope.sources`."""
        alias = node.args.get("alias")
        alias_name = alias.name.lower() if alias is not None and alias.name else None
        column_names = [ident_name(c) for c in alias.columns] if alias is not None and alias.columns else None
        if isinstance(node, exp.Table):
            if isinstance(node.this, (exp.Anonymous, exp.Func)):
                self.unsupported(
                    f"table function '{node.this.name if isinstance(node.this, exp.Anonymous) else node.this.key}'",
                    node,
                )
            if node.args.get("sample"):
                self.unsupported("TABLESAMPLE", node)
            if node.args.get("joins") or node.args.get("pivots"):
                self.unsupported("table sampling or pivot", node)
            name = node.name.lower()
            parts = [p.name.lower() for p in (node.args.get("catalog"), node.args.get("db")) if p is not None]
            cte = scope.cte(name) if not parts else None
            if cte is not None:
                cols = cte
            else:
                key = ".".join(parts + [name])
                if key not in self.schema:
                    self.fail(f"Table '{key}' does not exist", node, "TABLE_NOT_FOUND")
                cols = [(c, c, t) for c, t in self.schema[key]]
            qualifier = alias_name or name
            if alias is None:
                node.set("alias", exp.TableAlias(this=exp.to_identifier(qualifier, quoted=True)))
        elif isinstance(node, exp.Subquery):
            cols = self.query(node.this, lateral_scope or scope.derived())
            self._modifiers(node, cols, scope)
            qualifier = alias_name or self.fresh_alias()
            if alias is None:
                node.set("alias", exp.TableAlias(this=exp.to_identifier(qualifier, quoted=True)))
        elif isinstance(node, exp.Values):
            cols = self.values(node, lateral_scope or scope.derived())
            qualifier = alias_name or self.fresh_alias()
            if alias is None or not alias.columns:
                node.set(
                    "alias",
                    exp.TableAlias(
                        this=exp.to_identifier(qualifier, quoted=True),
                        columns=[exp.to_identifier(c[1], quoted=True) for c in cols],
                    ),
                )
        elif isinstance(node, exp.Unnest):
            cols = self.unnest(node, scope, column_names)
            qualifier = alias_name or self.fresh_alias()
            node.meta["qualifier"] = qualifier
            column_names = None
        elif isinstance(node, exp.Lateral):
            if not isinstance(node.this, exp.Subquery):
                self.unsupported("LATERAL", node)
            cols = self.query(node.this.this, scope)
            self._check_correlated_rows(node, scope)
            qualifier = alias_name or self.fresh_alias()
            if alias is None or (isinstance(node.this.this, exp.Values) and not alias.columns):
                columns = [exp.to_identifier(c[1], quoted=True) for c in cols]  # VALUES names them _col0, ...
                node.set(
                    "alias",
                    exp.TableAlias(
                        this=exp.to_identifier(qualifier, quoted=True),
                        columns=columns if isinstance(node.this.this, exp.Values) else [],
                    ),
                )
        else:
            self.unsupported(f"FROM item {node.key.upper()}", node)
        if column_names is not None:
            if len(column_names) != len(cols):
                self.fail(
                    f"Column alias list has {len(column_names)} entries but '{qualifier}' has {len(cols)} columns "
                    "available",
                    alias,
                    "MISMATCHED_COLUMN_ALIASES",
                )
            cols = [(n, n, c[2]) for n, c in zip(column_names, cols)]
        source = Source(alias_name or (node.name.lower() if isinstance(node, exp.Table) else None), qualifier, cols)
        if any(s.name is not None and s.name == source.name for s in scope.sources):
            self.fail(f"Duplicate relation name '{source.name}' in FROM clause", node, "DUPLICATE_NAMED_QUERY")
        scope.sources.append(source)

    def unnest(self, node: exp.Unnest, scope: NameScope, names: list[str] | None) -> list[OutCol]:
        lateral = NameScope(scope.sources, scope.outer, scope.ctes)
        offset = node.args.get("offset")
        if isinstance(offset, exp.Identifier) and names is not None:
            names = names + [ident_name(offset)]
        cols: list[OutCol] = []
        element_columns = []
        for arg in node.expressions:
            t = self.expr(arg, lateral, {})
            if t.base == "array":
                element = t.element
                if element.base == "row":
                    fields = [(n, f) for n, f in element.args]
                    element_columns.append(fields)
                    cols.extend((n, n or "", f) for n, f in fields)
                else:
                    element_columns.append([(None, element)])
                    cols.append((None, "", element))
            elif t.base == "map":
                element_columns.append([(None, t.args[0]), (None, t.args[1])])
                cols.extend([(None, "", t.args[0]), (None, "", t.args[1])])
            else:
                self.fail(f"Cannot unnest type: {t}", arg, "TYPE_MISMATCH")
        if node.args.get("offset"):
            cols.append((None, "", tt.BIGINT))
        if names is not None:
            if len(names) != len(cols):
                self.fail(
                    f"Column alias list has {len(names)} entries but UNNEST has {len(cols)} columns available",
                    node.args["alias"],
                    "MISMATCHED_COLUMN_ALIASES",
                )
            cols = [(n, n, c[2]) for n, c in zip(names, cols)]
        else:
            cols = [(c[0], c[0] or f"_col{i}", c[2]) for i, c in enumerate(cols)]
        node.meta["elements"] = element_columns
        node.meta["names"] = [c[1] for c in cols]
        return cols

    def join(self, join: exp.Join, scope: NameScope) -> None:
        kind = (join.args.get("kind") or "").upper()
        if (join.args.get("method") or "").upper() == "NATURAL":  # StatementAnalyzer.visitJoin refuses it so
            self.fail("Natural join not supported", join, "NOT_SUPPORTED")
        if (
            kind in ("SEMI", "ANTI", "ASOF", "POSITIONAL")
            or join.args.get("method")
            or join.args.get("match_condition")
        ):
            self.unsupported(f"{kind or join.args.get('method')} JOIN", join)
        beside = {source.qualifier for source in scope.sources}
        self.relation(
            join.this, scope, lateral_scope=scope if isinstance(join.this, (exp.Unnest, exp.Lateral)) else None
        )
        side = (join.args.get("side") or "").upper()
        if side in ("RIGHT", "FULL") and isinstance(join.this, (exp.Unnest, exp.Lateral)):
            self._check_outer_lateral(join, side, beside)
        on = join.args.get("on")
        if on is not None:
            self.condition(on, scope, "JOIN ON")
        using = join.args.get("using")
        if using:
            self.join_using(join, using, scope)

    def join_using(self, join: exp.Join, using: list, scope: NameScope) -> None:
        """JOIN ... USING (k): each k becomes one unqualified column of the common type, listed first by
        `*` (the left value, the right one for RIGHT JOIN, coalesced for FULL JOIN); `t.k` no longer
        resolves (io.trino.sql.analyzer.StatementAnalyzer.analyzeJoinUsing, io.trino.sql.query.TestJoinUsing)."""
        side = (join.args.get("side") or "").upper()
        joined: list[OutCol] = []
        sql: dict[str, str] = {}
        for ident in using:
            name = ident.name.lower()
            if name in sql:
                self.fail(
                    f"Column '{ident.name}' appears multiple times in USING clause", ident, "DUPLICATE_COLUMN_NAME"
                )
            left = [(s, c) for s in scope.sources[:-1] for c in s.find(name)]
            right = [(scope.sources[-1], c) for c in scope.sources[-1].find(name)]
            if not right or not left:
                self.fail(
                    f"Column '{ident.name}' is missing from {'right' if not right else 'left'} side of join",
                    ident,
                    "COLUMN_NOT_FOUND",
                )
            common = tt.common_super_type(left[0][1][2], right[0][1][2])
            if common is None:
                self.fail(f"Column types of '{ident.name}' in USING do not match", ident, "TYPE_MISMATCH")
            if common.base == "time_tz":  # DuckDB would join on whole structs, not the times at +00:00
                self.unsupported(f"JOIN USING ({ident.name}) of {common}", ident)
            if common.base == "char" and left[0][1][2] != right[0][1][2]:  # the join keys would need padding
                self.unsupported(f"JOIN USING ({ident.name}) of {left[0][1][2]} and {right[0][1][2]}", ident)
            self.zoned_cast_in_utc_only(left[0][1][2], right[0][1][2], ident, f"JOIN USING ({ident.name})")
            values = [_using_value(source, col, common) for source, col in (left[0], right[0])]
            sql[name] = {"RIGHT": values[1], "FULL": f"COALESCE({values[0]}, {values[1]})"}.get(side, values[0])
            joined.append((left[0][1][0], left[0][1][1], common))
        for index, source in enumerate(scope.sources):
            kept = [c for c in source.columns if c[0] is None or c[0].lower() not in sql]
            scope.sources[index] = Source(source.name, source.qualifier, kept, source.using)
        scope.sources.insert(0, Source(None, scope.sources[0].qualifier, joined, sql))

    def column(self, node: exp.Column, scope: NameScope, env: dict[str, TType]) -> TType:
        if node.meta.get("resolved"):
            return ttype(node)
        parts = [p.name for p in node.parts]
        quoted = [p.quoted for p in node.parts]
        lower = [p.lower() for p in parts]
        # lambda parameter with field access: x.name
        if lower[0] in env:
            t = env[lower[0]]
            node.meta["ref"] = (None, lower[0], ())
            node.meta["lambda"] = True
            return self._fields(node, t, parts[1:], quoted[1:])
        if scope.outputs is not None and len(parts) == 1:
            # ORDER BY sees the select's output names first
            matches = [c for c in scope.outputs if c[0] is not None and c[0].lower() == lower[0]]
            if len(matches) == 1:
                node.meta["ref"] = (None, matches[0][1], ())
                node.meta["output"] = True
                return matches[0][2]
        search: NameScope | None = scope
        while search is not None:
            # [schema.]table.column[.field ...] or column[.field ...]: the longest qualifier wins
            for split in range(min(len(parts) - 1, 2), -1, -1):
                sources = [s for s in search.sources if s.name == lower[split - 1]] if split else search.sources
                matches = [(s, c) for s in sources for c in s.find(lower[split])]
                if len(matches) > 1:
                    self.fail(f"Column '{parts[split]}' is ambiguous", node, "AMBIGUOUS_NAME")
                if matches:
                    source, col = matches[0]
                    node.meta["ref"] = (source.qualifier, col[1], ())
                    if col[1].lower() in source.using:
                        node.meta["sql"] = source.using[col[1].lower()]
                    return self._fields(node, col[2], parts[split + 1 :], quoted[split + 1 :])
            search = search.outer
        self.fail(f"Column '{'.'.join(parts)}' cannot be resolved", node, "COLUMN_NOT_FOUND")

    def _check_outer_lateral(self, join: exp.Join, side: str, beside: set[str]) -> None:
        """A RIGHT or FULL JOIN LATERAL (or UNNEST) may not use the columns beside it
        (INVALID_COLUMN_REFERENCE at the first such column), and a FULL one joins only ON TRUE
        (StatementAnalyzer, as the real Trino 476 says); the rest is refused: over an empty left
        side Trino gives no rows (the real Trino 476), which no outer join of DuckDB gives."""
        for column in join.this.find_all(exp.Column):
            if column._meta and column.meta.get("ref", (None,))[0] in beside:
                self.fail(f"LATERAL reference not allowed in {side} JOIN", column, "INVALID_COLUMN_REFERENCE")
        on = join.args.get("on")
        if side == "FULL" and isinstance(join.this, exp.Lateral) and on is not None and on != exp.true():
            message = "FULL JOIN involving LATERAL relation is only supported with condition ON TRUE"
            self.fail(message, on, "NOT_SUPPORTED")
        kind = "UNNEST" if isinstance(join.this, exp.Unnest) else "LATERAL"
        self.unsupported(  # Trino 476 joins the right side per row of the left: none when the left has none
            f"{side} JOIN {kind} (Trino gives no rows when the left side has none, where an outer join keeps the "
            "right side's; write it as a join of a subquery)",
            join.this,
        )

    def _check_correlated_rows(self, node: exp.Lateral, scope: NameScope) -> None:
        """A LATERAL subquery whose UNION, INTERSECT, EXCEPT or VALUES of several rows uses the columns
        beside it is one the real Trino 476 cannot decorrelate (NOT_SUPPORTED)."""
        query = node.this.this
        outer = {source.qualifier for source in scope.sources}
        outer -= {source.alias_or_name for source in query.find_all(exp.Table, exp.Subquery, exp.Values)}

        def correlated(part: exp.Expression) -> bool:
            return any(c._meta and c.meta.get("ref", (None,))[0] in outer for c in part.find_all(exp.Column))

        for part in query.find_all(exp.Values, exp.SetOperation):
            if (isinstance(part, exp.SetOperation) or len(part.expressions) > 1) and correlated(part):
                self.fail("Given correlated subquery is not supported", node.this, "NOT_SUPPORTED")

    def _fields(self, node: exp.Expression, t: TType, fields: list[str], quoted: list[bool]) -> TType:
        path = []
        for name, q in zip(fields, quoted):
            t, real = self.field(t, name, q, node)
            path.append(real)
        ref = node.meta["ref"]
        node.meta["ref"] = (ref[0], ref[1], tuple(path))
        return t

    def field(self, t: TType, name: str, quoted: bool, node: exp.Expression) -> tuple[TType, str]:
        if t.base != "row":
            self.fail(f"Expression of type {t} is not a row; cannot dereference '{name}'", node, "TYPE_MISMATCH")
        for field_name, field_type in t.args:
            if field_name is not None and field_name.lower() == name.lower():
                return field_type, field_name
        self.fail(f"Column '{name}' cannot be resolved", node, "COLUMN_NOT_FOUND")


def _is_row_call(node: exp.Expression) -> bool:
    """Whether `node` is written ROW(...)."""
    return isinstance(node, exp.Anonymous) and node.name.upper() == "ROW"

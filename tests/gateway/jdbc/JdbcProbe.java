import java.sql.Connection;
import java.sql.DatabaseMetaData;
import java.sql.DriverManager;
import java.sql.PreparedStatement;
import java.sql.ResultSet;
import java.sql.ResultSetMetaData;
import java.sql.SQLException;
import java.util.Properties;

/**
 * Drives the official Trino JDBC driver against one server and prints one JSON object per line for
 * each call: {"call": ..., "columns": [[label, type name, java.sql.Types], ...], "rows": [[...], ...]}
 * or {"call": ..., "error": message}.
 *
 * <p>Usage: java -cp trino-jdbc.jar:. JdbcProbe URL USER CATALOG SCHEMA TABLE [-- QUERY [PARAMETER ...]]...
 *
 * <p>The DatabaseMetaData calls are made with the arguments DBeaver and DataGrip pass when they
 * browse a catalog tree: every catalog, the schemas of a catalog ('%' or none), the tables of a
 * schema (no pattern; '%'; '%' with the types TABLE and VIEW), the columns of one table (by its
 * name, and by its name escaped with getSearchStringEscape as DataGrip passes it) and of the whole
 * schema, the type list, the table types, the procedures (and their columns), user-defined types,
 * super types, super tables and attributes of the schema, and the pseudo columns, keys and indexes
 * of the table. Each QUERY is then run as a PreparedStatement with each
 * PARAMETER bound in turn (setLong when it parses as an integer, else setString).
 */
public final class JdbcProbe {
    private JdbcProbe() {}

    public static void main(String[] args) throws Exception {
        String url = args[0];
        String catalog = args[2];
        String schema = args[3];
        String table = args[4];
        Properties properties = new Properties();
        properties.setProperty("user", args[1]);
        try (Connection connection = DriverManager.getConnection(url, properties)) {
            DatabaseMetaData meta = connection.getMetaData();
            String escape = meta.getSearchStringEscape();
            String escaped = table.replace(escape, escape + escape).replace("_", escape + "_").replace("%", escape + "%");
            print("product", "{\"name\": " + json(meta.getDatabaseProductName()) + ", \"version\": "
                    + json(meta.getDatabaseProductVersion()) + "}");
            call("getCatalogs()", meta::getCatalogs);
            call("getSchemas()", meta::getSchemas);
            call("getSchemas(catalog, null)", () -> meta.getSchemas(catalog, null));
            call("getSchemas(catalog, %)", () -> meta.getSchemas(catalog, "%"));
            call("getSchemas(catalog, schema)", () -> meta.getSchemas(catalog, schema));
            call("getTables(catalog, schema, null, null)", () -> meta.getTables(catalog, schema, null, null));
            call("getTables(catalog, schema, %, null)", () -> meta.getTables(catalog, schema, "%", null));
            call("getTables(catalog, schema, %, TABLE VIEW)",
                    () -> meta.getTables(catalog, schema, "%", new String[] {"TABLE", "VIEW"}));
            call("getTables(catalog, schema, table, null)", () -> meta.getTables(catalog, schema, table, null));
            call("getColumns(catalog, schema, table, null)", () -> meta.getColumns(catalog, schema, table, null));
            call("getColumns(catalog, schema, escaped table, %)",
                    () -> meta.getColumns(catalog, schema, escaped, "%"));
            call("getColumns(catalog, schema, %, %)", () -> meta.getColumns(catalog, schema, "%", "%"));
            call("getTypeInfo()", meta::getTypeInfo);
            call("getTableTypes()", meta::getTableTypes);
            call("getProcedures(catalog, schema, %)", () -> meta.getProcedures(catalog, schema, "%"));
            call("getUDTs(catalog, schema, %, null)", () -> meta.getUDTs(catalog, schema, "%", null));
            call("getProcedureColumns(catalog, schema, %, %)",
                    () -> meta.getProcedureColumns(catalog, schema, "%", "%"));
            call("getSuperTypes(catalog, schema, %)", () -> meta.getSuperTypes(catalog, schema, "%"));
            call("getSuperTables(catalog, schema, %)", () -> meta.getSuperTables(catalog, schema, "%"));
            call("getAttributes(catalog, schema, %, %)", () -> meta.getAttributes(catalog, schema, "%", "%"));
            call("getPseudoColumns(catalog, schema, table, %)",
                    () -> meta.getPseudoColumns(catalog, schema, table, "%"));
            call("getPrimaryKeys(catalog, schema, table)", () -> meta.getPrimaryKeys(catalog, schema, table));
            call("getImportedKeys(catalog, schema, table)", () -> meta.getImportedKeys(catalog, schema, table));
            call("getIndexInfo(catalog, schema, table)",
                    () -> meta.getIndexInfo(catalog, schema, table, false, true));
            for (int at = 5; at < args.length; ) {
                int next = at + 1;
                while (next < args.length && !args[next].equals("--")) {
                    next++;
                }
                try (PreparedStatement statement = connection.prepareStatement(args[at + 1])) {
                    for (int i = at + 2; i < next; i++) {
                        try {
                            statement.setLong(i - at - 1, Long.parseLong(args[i]));
                        } catch (NumberFormatException notANumber) {
                            statement.setString(i - at - 1, args[i]);
                        }
                    }
                    call("PreparedStatement " + args[at + 1], statement::executeQuery);
                }
                at = next;
            }
        }
    }

    private interface Call {
        ResultSet run() throws SQLException;
    }

    private static void call(String name, Call call) {
        try (ResultSet rows = call.run()) {
            ResultSetMetaData meta = rows.getMetaData();
            StringBuilder out = new StringBuilder("{\"columns\": [");
            for (int i = 1; i <= meta.getColumnCount(); i++) {
                out.append(i > 1 ? ", " : "").append('[').append(json(meta.getColumnLabel(i))).append(", ")
                        .append(json(meta.getColumnTypeName(i))).append(", ").append(meta.getColumnType(i)).append(']');
            }
            out.append("], \"rows\": [");
            boolean first = true;
            while (rows.next()) {
                out.append(first ? "[" : ", [");
                first = false;
                for (int i = 1; i <= meta.getColumnCount(); i++) {
                    out.append(i > 1 ? ", " : "").append(value(rows.getObject(i)));
                }
                out.append(']');
            }
            print(name, out.append("]}").toString());
        } catch (SQLException error) {
            print(name, "{\"error\": " + json(error.getMessage()) + "}");
        }
    }

    private static void print(String name, String body) {
        System.out.println("{\"call\": " + json(name) + ", \"result\": " + body + "}");
    }

    private static String value(Object value) {
        if (value == null) {
            return "null";
        }
        if (value instanceof Number || value instanceof Boolean) {
            return value.toString();
        }
        if (value instanceof java.sql.Array array) {
            try {
                return json(java.util.Arrays.deepToString((Object[]) array.getArray()));
            } catch (SQLException error) {
                return json(error.getMessage());
            }
        }
        return json(value.toString());
    }

    private static String json(String text) {
        if (text == null) {
            return "null";
        }
        StringBuilder out = new StringBuilder("\"");
        for (char c : text.toCharArray()) {
            if (c == '"' || c == '\\') {
                out.append('\\').append(c);
            } else if (c < 0x20) {
                out.append(String.format("\\u%04x", (int) c));
            } else {
                out.append(c);
            }
        }
        return out.append('"').toString();
    }
}

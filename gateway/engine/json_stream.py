"""Jackson's streaming read of JSON text, as Trino 476's JSONPath and JSON array functions do it
(io.trino.util.JsonUtil.JSON_FACTORY: Jackson's ReaderBasedJsonParser with its default features: no
comments, NaN, single quotes, leading zeros, leading '+' or '.', or trailing commas). Each function
reads only as far as its answer needs, so a text malformed after that point still answers;
`MalformedJson` is raised where Jackson raises JsonParseException (the functions answer NULL).

Tokens are the strings of `START`/`END` and `NAME`, `STRING`, `INT`, `FLOAT`, `TRUE`, `FALSE`,
`NULL`. As in Jackson, a string value is read (and checked) only when asked for or when the next
token is read; a number is checked as a token (a root-level number must be followed by white space);
a name's value token is found when the name is read.
"""

from __future__ import annotations

import re
import unicodedata

START_OBJECT, END_OBJECT, START_ARRAY, END_ARRAY = "{", "}", "[", "]"
NAME, STRING, INT, FLOAT, TRUE, FALSE, NULL = "name", "string", "int", "float", "true", "false", "null"
SCALARS = (STRING, INT, FLOAT, TRUE, FALSE)


class MalformedJson(ValueError):
    """The text is not JSON at the point read (Jackson's JsonParseException)."""


_WHITE = re.compile(r"[ \t\n\r]*")
_PLAIN = re.compile(r'[^"\\\x00-\x1f]*')
_NUMBER = re.compile(r"-?(0|[1-9][0-9]*)?(\.[0-9]*)?([eE][+-]?[0-9]*)?")
_ESCAPES = {'"': '"', "\\": "\\", "/": "/", "b": "\b", "f": "\f", "n": "\n", "r": "\r", "t": "\t"}
_HEX = re.compile(r"[0-9A-Fa-f]{4}")
_LITERALS = {"t": ("true", TRUE), "f": ("false", FALSE), "n": ("null", NULL)}
_SURROGATE = re.compile("[\ud800-\udfff]")
#: Java's Character.isJavaIdentifierPart: letters, digits, connectors, currency, marks, ignorables.
_IDENTIFIER_CATEGORIES = frozenset({"Lu", "Ll", "Lt", "Lm", "Lo", "Nl", "Nd", "Pc", "Sc", "Mn", "Mc", "Cf"})


def _identifier_part(ch: str) -> bool:
    code = ord(ch)
    return (
        unicodedata.category(ch) in _IDENTIFIER_CATEGORIES or code <= 8 or 0x0E <= code <= 0x1B or 0x7F <= code <= 0x9F
    )


def java_string(units: str) -> str:
    """A decoded string as Java holds it: escaped surrogate pairs joined (a lone surrogate stays)."""
    if not _SURROGATE.search(units):
        return units
    return units.encode("utf-16-le", "surrogatepass").decode("utf-16-le", "surrogatepass")


def utf8_text(text: str) -> str:
    """A Java string as Trino's varchar holds it (String.getBytes(UTF_8)): a lone surrogate is '?'."""
    return _SURROGATE.sub("?", text)


class Parser:
    """The token stream of one JSON text, read on demand (Jackson's nextToken / skipChildren)."""

    def __init__(self, text: str) -> None:
        self.s, self.i, self.n = text, 0, len(text)
        self.stack: list[list] = [["root", -1]]  # [kind, index of the current entry]
        self.token: str | None = None
        self.raw = ""  # the text of a number or literal token as written
        self.name = ""  # the current name
        self._string: int | None = None  # where the current string value starts, not read yet
        self._decoded = ""
        self._after_name: str | None = None

    # --- tokens -------------------------------------------------------------------------------
    def next_token(self) -> str | None:
        """The next token (None at the end of a root-level text); MalformedJson where Jackson fails."""
        if self.token == NAME:
            self.token = self._after_name
            if self.token in (START_ARRAY, START_OBJECT):
                self.stack.append(["array" if self.token == START_ARRAY else "object", -1])
            return self.token
        if self._string is not None:
            self.text()  # Jackson skips (and checks) the string it did not read
        c = self._skip_white()
        if c is None:
            if len(self.stack) > 1:
                raise MalformedJson("unexpected end of input")
            self.token = None
            return None
        context = self.stack[-1]
        if c in "]}":
            if context[0] != ("array" if c == "]" else "object"):
                raise MalformedJson(f"unexpected close marker {c!r}")
            self.i += 1
            self.stack.pop()
            self.token = END_ARRAY if c == "]" else END_OBJECT
            return self.token
        context[1] += 1
        if context[0] != "root" and context[1] > 0:
            if c != ",":
                raise MalformedJson("expected a comma between entries")
            self.i += 1
            c = self._skip_white(required=True)
        if context[0] == "object":
            if c != '"':
                raise MalformedJson("expected a double-quote to start a field name")
            self.i += 1
            self.name = java_string(self._read_string())
            if self._skip_white(required=True) != ":":
                raise MalformedJson("expected a colon after a field name")
            self.i += 1
            self._after_name = self._value(self._skip_white(required=True), nested=False)
            self.token = NAME
            return NAME
        self.token = self._value(c, nested=True)
        return self.token

    def skip_children(self) -> None:
        """Read past the end of the current array or object (nothing for another token)."""
        if self.token not in (START_ARRAY, START_OBJECT):
            return
        depth = 1
        while depth:
            token = self.next_token()
            if token in (START_ARRAY, START_OBJECT):
                depth += 1
            elif token in (END_ARRAY, END_OBJECT) or token is None:
                depth -= 1

    def text(self) -> str:
        """The current string's value (read now, if not yet), or the token's text as written."""
        if self.token == NAME:
            return self.name
        if self._string is not None:
            self.i, self._string = self._string, None
            self._decoded = java_string(self._read_string())
        return self._decoded if self.token == STRING else self.raw

    # --- reading --------------------------------------------------------------------------------
    def _skip_white(self, required: bool = False) -> str | None:
        self.i = _WHITE.match(self.s, self.i).end()
        if self.i < self.n:
            return self.s[self.i]
        if required:
            raise MalformedJson("unexpected end of input")
        return None

    def _value(self, c: str, nested: bool) -> str:
        """The token starting at `c` (a container's context is opened when its token is returned)."""
        if c == '"':
            self.i += 1
            self._string = self.i  # read (and checked) by `text`, or when the next token is read
            return STRING
        if c in "[{":
            self.i += 1
            if nested:
                self.stack.append(["array" if c == "[" else "object", -1])
            return START_ARRAY if c == "[" else START_OBJECT
        if c in _LITERALS:
            word, token = _LITERALS[c]
            if not self.s.startswith(word, self.i):
                raise MalformedJson("unrecognized token")
            self.i += len(word)
            if self.i < self.n:
                after = self.s[self.i]
                if after >= "0" and after not in "]}" and _identifier_part(after):
                    raise MalformedJson("unrecognized token")
            self.raw = word
            return token
        if c == "-" or "0" <= c <= "9":
            return self._number()
        raise MalformedJson(f"unexpected character {c!r}")

    def _number(self) -> str:
        start = self.i
        match = _NUMBER.match(self.s, self.i)
        whole, fraction, exponent = match.group(1), match.group(2), match.group(3)
        if whole is None:
            raise MalformedJson("expected a digit")
        end = match.end()
        if whole == "0" and fraction is None and exponent is None and self._digit_at(end):
            raise MalformedJson("leading zeroes not allowed")
        if fraction == "." or (exponent is not None and not exponent.lstrip("eE+-")):
            raise MalformedJson("expected a digit")
        self.i = end
        if self.stack[-1][0] == "root" and end < self.n and self.s[end] not in " \t\n\r":
            raise MalformedJson("expected space separating root-level values")
        self.raw = self.s[start:end]
        return FLOAT if fraction or exponent else INT

    def _digit_at(self, position: int) -> bool:
        return position < self.n and "0" <= self.s[position] <= "9"

    def _read_string(self) -> str:
        """The string from the position (after its opening quote), its escapes decoded; the position
        is left after the closing quote."""
        s, parts = self.s, []
        while True:
            end = _PLAIN.match(s, self.i).end()
            parts.append(s[self.i : end])
            if end >= self.n:
                raise MalformedJson("unexpected end of input in a string")
            c, self.i = s[end], end + 1
            if c == '"':
                return "".join(parts)
            if c != "\\":
                raise MalformedJson("illegal unquoted character in a string")
            if self.i >= self.n:
                raise MalformedJson("unexpected end of input in an escape")
            e = s[self.i]
            self.i += 1
            if e in _ESCAPES:
                parts.append(_ESCAPES[e])
            elif e == "u" and _HEX.match(s, self.i):
                parts.append(chr(int(s[self.i : self.i + 4], 16)))
                self.i += 4
            else:
                raise MalformedJson("unrecognized escape")

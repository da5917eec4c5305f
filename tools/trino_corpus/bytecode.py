"""The QueryAssertions calls of Trino's compiled tests, read from `javap -c -p -constants`: a small
symbolic stack over each method's instructions that follows string constants into `function(...)`,
`expression(...)`, `.binding(...)`, `operator(...)` and `query(...)`. Straight-line code only: a
call whose strings are computed (a variable, a concatenation, a loop) is kept as `computed`."""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass, field

_CLASS = re.compile(r"^(?:public |final |abstract |private |protected |static )*(?:class|interface|enum) (\S+)")
_METHOD = re.compile(r"^  \S.*\);$|^  static \{\};$")
_INSTRUCTION = re.compile(r"^\s+\d+: (\w+)\s*(.*)$")
_STRING = re.compile(r"// String (.*)$")
_MEMBER = re.compile(r"// (?:Interface)?Method ([\w/$]+)\.([\w<>\"$]+):\((.*?)\)(\S+)")
_DYNAMIC = re.compile(r"// InvokeDynamic #\d+:\w+:\((.*?)\)(\S+)")
_STATIC_FIELD = re.compile(r"// Field ([\w/$]+)\.(\w+):")
_ESCAPE = re.compile(r"\\(u[0-9a-fA-F]{4}|.)")
_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "b": "\b", "f": "\f", "0": "\0"}

_ASSERTIONS = "io/trino/sql/query/QueryAssertions"
_PROVIDER = "io/trino/sql/query/QueryAssertions$ExpressionAssertProvider"
_OPERATOR_TYPE = "io/trino/spi/function/OperatorType"
_PUSHES = frozenset(
    "aconst_null aload aload_0 aload_1 aload_2 aload_3 iload iload_0 iload_1 iload_2 iload_3 lload lload_0 lload_1 "
    "lload_2 lload_3 dload dload_0 dload_1 dload_2 dload_3 fload fload_0 fload_1 fload_2 fload_3 new lconst_0 "
    "lconst_1 dconst_0 dconst_1 fconst_0 fconst_1 fconst_2 ldc2_w".split()
)
_POPS = frozenset(
    "pop astore astore_0 astore_1 astore_2 astore_3 istore istore_0 istore_1 istore_2 istore_3 lstore lstore_1 "
    "lstore_2 lstore_3 dstore dstore_1 dstore_2 dstore_3 fstore putstatic".split()
)


class Computed:
    """A value the stack does not know (a variable, a call's result, a concatenation)."""


COMPUTED = Computed()


@dataclass
class Call:
    """One QueryAssertions call: `kind` is function, expression, operator or query."""

    where: str  # class.method
    kind: str
    text: str  # the function name, the expression, the operator or the query
    arguments: list = field(default_factory=list)  # function and operator arguments
    bindings: list = field(default_factory=list)  # (name, value) of expression bindings

    @property
    def computed(self) -> bool:
        """Whether a string of the call is not a constant of the class file."""
        values = [self.text, *self.arguments, *(v for pair in self.bindings for v in pair)]
        return not all(isinstance(v, str) for v in values)


def unescape(text: str) -> str:
    """A string constant as javap prints it (`\\'`, `\\n`, `\\u007f`) back to the string."""

    def one(match: re.Match) -> str:
        code = match.group(1)
        if code.startswith("u") and len(code) == 5:
            return chr(int(code[1:], 16))
        return _ESCAPES.get(code, code)

    return _ESCAPE.sub(one, text)


def _argument_count(descriptor: str) -> int:
    return len(re.findall(r"\[*(?:L[^;]+;|[BCDFIJSZ])", descriptor))


def calls(javap_lines: Iterable[str]) -> list[Call]:
    """Every QueryAssertions call in javap's disassembly of one or more classes, in order."""
    owner, method, stack, found = "", "", [], []

    def pop():
        return stack.pop() if stack else COMPUTED

    for line in javap_lines:
        line = line.rstrip("\n")
        declared = _CLASS.match(line)
        if declared:
            owner = declared.group(1).rsplit(".", 1)[-1]
            continue
        if _METHOD.match(line):
            method, stack = line.split("(")[0].split()[-1], []
            continue
        instruction = _INSTRUCTION.match(line)
        if not instruction:
            continue
        opcode, rest = instruction.groups()
        if opcode in ("ldc", "ldc_w"):
            string = _STRING.search(rest)
            stack.append(unescape(string.group(1)) if string else COMPUTED)
        elif opcode.startswith("iconst_"):
            stack.append(-1 if opcode == "iconst_m1" else int(opcode[-1]))
        elif opcode in ("bipush", "sipush"):
            stack.append(int(rest.split()[0]))
        elif opcode == "getstatic":
            field_ = _STATIC_FIELD.search(rest)
            operator = field_ and field_.group(1) == _OPERATOR_TYPE
            stack.append(("operator", field_.group(2)) if operator else COMPUTED)
        elif opcode in _PUSHES:
            stack.append(COMPUTED)
        elif opcode in _POPS:
            pop()
        elif opcode == "getfield":
            pop()
            stack.append(COMPUTED)
        elif opcode == "checkcast":
            pass
        elif opcode == "dup":
            stack.append(stack[-1] if stack else COMPUTED)
        elif opcode == "anewarray":
            count = pop()
            stack.append([COMPUTED] * count if isinstance(count, int) and 0 <= count < 1000 else COMPUTED)
        elif opcode == "aastore":
            value, index, array = pop(), pop(), pop()
            if isinstance(array, list) and isinstance(index, int) and 0 <= index < len(array):
                array[index] = value
        elif opcode.startswith("invoke"):
            made = _invoke(opcode, rest, f"{owner}.{method}", stack, pop)
            if made is not None:
                found.append(made)
        else:  # a branch, an arithmetic or another instruction: what the stack held is forgotten
            stack.clear()
    return found


def _invoke(opcode: str, rest: str, where: str, stack: list, pop) -> Call | None:
    """Apply one invoke instruction to the stack; the Call it starts, if any."""
    dynamic = _DYNAMIC.search(rest) if opcode == "invokedynamic" else None
    member = None if dynamic else _MEMBER.search(rest)
    if not dynamic and not member:
        stack.clear()
        return None
    descriptor, returns = dynamic.groups() if dynamic else member.group(3, 4)
    arguments = [pop() for _ in range(_argument_count(descriptor))][::-1]
    receiver = pop() if opcode in ("invokevirtual", "invokeinterface", "invokespecial") else None
    result = COMPUTED
    if member:
        owner, name = member.group(1), member.group(2)
        if owner == _ASSERTIONS and name == "function" and descriptor.endswith("[Ljava/lang/String;"):
            listed = arguments[1] if isinstance(arguments[1], list) else [COMPUTED]
            result = Call(where, "function", arguments[0], arguments=list(listed))
        elif owner == _ASSERTIONS and name == "expression":
            result = Call(where, "expression", arguments[0])
        elif owner == _ASSERTIONS and name == "operator":
            operator = arguments[0][1] if isinstance(arguments[0], tuple) else COMPUTED
            listed = arguments[1] if isinstance(arguments[1], list) else [COMPUTED]
            result = Call(where, "operator", operator, arguments=list(listed))
        elif owner == _ASSERTIONS and name in ("query", "assertQueryReturnsEmptyResult", "execute"):
            result = Call(where, "query", arguments[-1])
        elif owner == _PROVIDER and name == "binding" and isinstance(receiver, Call):
            receiver.bindings.append((arguments[0], arguments[1]))
            result = receiver
    if returns != "V":
        stack.append(result)
    return result if isinstance(result, Call) and result is not receiver else None

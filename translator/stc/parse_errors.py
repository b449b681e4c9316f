"""Syntax errors: the one-line message of an unexpected token, and the recovery that lets
the parser go on after it so every syntax error of a file is reported."""
from lark import Token
from lark.exceptions import UnexpectedCharacters, UnexpectedInput, UnexpectedToken

from . import syntax as S


_TOKEN_TEXT = {
    "ASSIGN": "':='", "ARROW": "'=>'", "COLON": "':'", "SEMI": "';'", "COMMA": "','",
    "DOTDOT": "'..'", "DOT": "'.'", "LPAR": "'('", "RPAR": "')'", "LBRACK": "'['",
    "RBRACK": "']'", "AMP": "'&'", "EQ": "'='", "NE": "'<>'", "LT": "'<'", "GT": "'>'",
    "LE": "'<='", "GE": "'>='", "PLUS": "'+'", "MINUS": "'-'", "POW": "'**'", "STAR": "'*'",
    "SLASH": "'/'", "DEREF": "'^'", "IDENT": "an identifier", "INTEGER": "an integer",
    "BASED_INT": "an integer", "REAL_LIT": "a REAL literal", "TIME_LIT": "a TIME literal",
    "TYPED_PREFIX": "a typed literal", "DIRECT": "a direct address", "STRING_LIT": "a string",
    "$END": "end of file",
}

_KEYWORD_TYPES = {"ON", "AT", "TASK", "WITH", "CONTINUE", "EXIT", "RETURN", "BY", "TO", "DO", "OF",
                  "CONSTANT", "RETAIN", "NON_RETAIN", "THEN", "ELSE", "ELSIF", "UNTIL", "TYPE",
                  "ARRAY", "STRUCT", "PROGRAM", "FUNCTION", "FUNCTION_BLOCK", "RESOURCE",
                  "CONFIGURATION", "VAR", "IF", "CASE", "FOR", "WHILE", "REPEAT", "MOD", "NOT",
                  "AND", "OR", "XOR", "TRUE", "FALSE"}


_NAMEY = {"ON", "AT", "TASK", "WITH", "BY", "TO", "DO", "OF", "CONTINUE", "EXIT", "RETURN",
          "CONSTANT", "RETAIN", "NON_RETAIN", "TYPE", "MOD", "STRUCT", "ARRAY"}


def _describe(tok_type):
    if tok_type in _TOKEN_TEXT:
        return _TOKEN_TEXT[tok_type]
    return tok_type


class _Recovery:
    """Error recovery: report an error, then drop tokens until the parser can go on.

    A new error is only reported after the parser has consumed a ';' (or a block end)
    since the previous one, so one mistake does not produce a cascade of messages."""

    def __init__(self, report):
        self.report = report
        self.last_line = 0
        self.skipping = False

    def _new(self, line):
        # one message per line: the tokens dropped while recovering do not cascade
        if line > self.last_line:
            self.last_line = line
            return True
        return False

    def __call__(self, e):
        if isinstance(e, UnexpectedCharacters):
            if self._new(e.line):
                ch = e.char
                if ch == "'" or ch == '"':
                    msg = f"string literal not closed on its line: missing {ch}"
                else:
                    msg = f"unexpected character {ch!r}"
                self.report((e.line, e.column), "P0108", msg)
            return True
        if isinstance(e, UnexpectedToken):
            tok = e.token
            pos = _tok_pos(tok, e)
            if tok.type == "$END" or self._new(pos[0]):
                self.report(pos, "P0104", _unexpected_message(e))
            if tok.type == "$END":
                return False
            if self.skipping:
                if tok.type == "SEMI":
                    self.skipping = False
                return True
            # a missing ';' is the commonest slip: insert one when it lets the parser go on
            if "SEMI" in e.expected and tok.type != "SEMI":
                ip = e.interactive_parser
                try:
                    probe = ip.copy(deepcopy_values=False)  # reductions build new nodes only
                    probe.feed_token(Token("SEMI", ";", 0, tok.line, tok.column, tok.line, tok.column, 0))
                    probe.feed_token(tok)
                except UnexpectedInput:
                    pass
                else:
                    ip.feed_token(Token("SEMI", ";", 0, tok.line, tok.column, tok.line, tok.column, 0))
                    ip.feed_token(tok)
                    return True
            # panic mode: abandon the statement (or declaration) being parsed and skip to the
            # next ';'
            ps = e.interactive_parser.parser_state
            states = ps.parse_conf.parse_table.states
            stack = ps.state_stack
            depth = len(stack)
            while depth > 1:
                acts = states[stack[depth - 1]]
                if tok.type in acts or "IF" in acts or "END_VAR" in acts:
                    break
                depth -= 1
            if depth > 1:
                drop = len(stack) - depth
                if drop:
                    del stack[depth:]
                    del ps.value_stack[len(ps.value_stack) - drop:]
                if tok.type in states[stack[-1]]:
                    try:
                        e.interactive_parser.feed_token(tok)
                    except UnexpectedInput:
                        pass
                    return True
                if tok.type != "SEMI":
                    self.skipping = True
            return True
        return False


def _tok_pos(tok, e):
    line = getattr(tok, "line", None) or getattr(e, "line", None) or 0
    col = getattr(tok, "column", None) or getattr(e, "column", None) or 0
    if line == -1 or line is None:
        line, col = 0, 0
    return (line, col)


_END_ORDER = ["END_IF", "END_CASE", "END_FOR", "END_WHILE", "END_REPEAT", "END_VAR", "END_STRUCT",
              "END_TYPE", "END_FUNCTION", "END_FUNCTION_BLOCK", "END_PROGRAM", "END_RESOURCE",
              "END_CONFIGURATION"]
_STMT_START = {"IDENT", "IF", "CASE", "FOR", "WHILE", "REPEAT", "EXIT", "CONTINUE", "RETURN"}


def _unexpected_message(e):
    tok = e.token
    exp = set(e.expected)
    prev = None
    try:
        top = e.interactive_parser.parser_state.value_stack[-1]
        if isinstance(top, Token):
            prev = top
        elif isinstance(top, S.NamedType) and tok.type in ("IDENT", "TO"):
            prev = Token("IDENT", top.name)
    except (AttributeError, IndexError):
        pass
    if tok.type == "$END":
        for x in ("END_PROGRAM", "END_FUNCTION_BLOCK", "END_FUNCTION"):
            if x in exp:
                return f"unexpected end of file: missing {x}"
        for x in _END_ORDER:
            if x in exp:
                return f"unexpected end of file: missing {x}"
        return "unexpected end of file"
    if prev is not None and prev.type == "IDENT" and str(prev).upper() in ("POINTER", "REF_TO", "REF"):
        return f"{str(prev).upper()} is not portable (matiec rejects pointers and references)"
    if prev is not None and str(prev).upper() == "METHOD" or tok.type == "IDENT" and str(tok).upper() == "METHOD":
        return "METHOD is not portable (matiec rejects it): use a separate FUNCTION_BLOCK or FUNCTION"
    if (prev is not None and prev.type in _KEYWORD_TYPES and tok.type in ("COLON", "ASSIGN", "COMMA")
            and prev.type not in ("END_IF", "END_CASE", "END_FOR", "END_WHILE", "END_REPEAT")):
        return f"'{prev}' is a reserved keyword and cannot be used as an identifier"
    text = str(tok)
    if tok.type == "IDENT":
        what = f"identifier '{text}'"
    elif tok.type in _TOKEN_TEXT:
        what = f"'{text}'"
    else:
        what = f"'{text}'"
        if "IDENT" in exp and tok.type in _NAMEY:
            return (f"'{text}' is a reserved keyword and cannot be used as an identifier"
                    if tok.type not in ("TRUE", "FALSE") else f"unexpected {what}")
    if "SEMI" in exp and (len(exp) <= 3 or tok.type in _STMT_START):
        if prev is not None and prev.type in ("END_IF", "END_CASE", "END_FOR", "END_WHILE", "END_REPEAT"):
            return f"missing ';' after {prev.type} (matiec requires it) before {what}"
        return f"expected ';' before {what}"
    if {"INTEGER", "IDENT", "LPAR"} <= exp:
        return f"unexpected {what}, expected an expression"
    if tok.type == "COLON" and "ASSIGN" in exp:
        return "unexpected ':' (did you mean ':='?)"
    shown = sorted(_describe(x) for x in exp)
    if len(shown) <= 6 and shown:
        return f"unexpected {what}, expected " + " or ".join(shown)
    return f"unexpected {what}"

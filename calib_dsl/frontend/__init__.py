"""The front end: the Lark grammar, the AST, the parser and file:line:col diagnostics."""

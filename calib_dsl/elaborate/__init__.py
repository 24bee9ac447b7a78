"""Elaboration: scopes, statements, expressions, robot chains and tables: from the AST
to the DAG."""

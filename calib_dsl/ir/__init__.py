"""The intermediate representation: the expression DAG with hash-consing, the elaborated model and
the flat program's data types.
"""

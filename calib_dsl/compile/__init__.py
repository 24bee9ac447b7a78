"""From the DAG to primitives: decomposition, grouping into the flat program, the listing."""

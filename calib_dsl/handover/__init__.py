"""The handover report (`calibc report`, `solve --report`): one self-contained HTML file
made from the JSON documents of a solve, a validation and an identification, for the reader
who takes the robot over. It only renders what those documents hold; `provenance.py` adds to a
solve's JSON what the report needs to say where a result came from.
"""

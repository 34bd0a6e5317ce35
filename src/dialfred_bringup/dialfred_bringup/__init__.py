"""DialFRED bring-up: the client side of the node graph.

`graph` starts node executables as supervised processes and gives a client node to call them; `launch`
is `./dialfred launch` (its jobs: demo, explore, nodes, dialogue, eval); `evaluation` and `local` run
benchmark evaluations through the graph or in worker processes; `shards` splits and merges them;
`replay`, `live` and `report` show recorded and running episodes; `reproduce` makes the paper's tables.
"""

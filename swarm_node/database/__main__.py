"""`python -m swarm_node.database`: print the table reference of docs/database.md."""

from .tables import render_markdown

print(render_markdown(), end="")

"""wbcbench: whole-body controller benchmark."""

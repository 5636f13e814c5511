"""Benchmarks of how much the code does in a second: the node's tick against carts and rate
(scaling, its report scaling_report), the tick's parts (tick_parts), a sweep's runs (sweep), a
field worked (field)."""

"""The BSP tree builders: the one-polygon builder and the lock-step batch builder."""

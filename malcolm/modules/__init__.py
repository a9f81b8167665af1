"""Block types by hardware module, as the design document imports them."""

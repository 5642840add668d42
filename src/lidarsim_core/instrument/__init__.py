"""The instrument: the sensor datasheet and its catalogue, beam divergence, the link budget and
the grouping of hits into returns."""

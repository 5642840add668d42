"""``lidarsim bench``: ray-casting throughput of every backend (:mod:`.throughput`) and the
whole simulation on realistic scenes against bare Embree (:mod:`.suite`)."""

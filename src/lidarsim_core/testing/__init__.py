"""Conformance suites that built-in and third-party plugins run against themselves.

Import these only from tests: they use pytest. For example, a ray-backend author writes::

    from lidarsim_core.testing.backends import BackendConformance

    class TestMyBackend(BackendConformance):
        backend_name = "mine"
"""

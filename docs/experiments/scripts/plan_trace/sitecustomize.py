"""Experiment-only tracer (helper C, s22): per planning cycle / field build decomposition of
wall time into thread CPU, run-queue wait (schedstat), helper-process time, rest (GIL/lock)."""
import os
import sys

PATH = os.environ.get("AUTOCHAIR_PLAN_TRACE")
if PATH:
    import importlib.abc
    import importlib.machinery

    class _Finder(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path, target=None):
            if name != "autochair.runtime":
                return None
            spec = importlib.machinery.PathFinder.find_spec(name, path)
            if spec is None:
                return None
            orig = spec.loader.exec_module

            def exec_module(module):
                orig(module)
                sm = module.service_main

                def service_main(name, cfg, start, *a, **k):
                    if name == "control":
                        import plantrace
                        plantrace.patch(sys.modules[start.__module__], PATH)
                    return sm(name, cfg, start, *a, **k)
                module.service_main = service_main
            spec.loader.exec_module = exec_module
            return spec

    sys.meta_path.insert(0, _Finder())

"""A run's configuration, gathered: what it is and where it comes from.

================  ==================================================================
module            what it holds
================  ==================================================================
``knobs``         ``knob``: a field declared once (default, help, the paper's or not)
``backends``      ``Stack``, the back-ends section
``run``           ``RunConfig``, the whole tree, with its scene and eval sections
``presets``       the named configurations (``toml/NAME.toml``), ``--config`` files and
                  dotted overrides, resolved into a tree
``inert``         which settings do not act in a given run (refused, or commented)
================  ==================================================================

The explore, stop and answer sections are declared beside the code they configure
(``explore/config.py``, ``stop/rules.py``, ``answer/config.py``) with ``knobs.knob``. This
package imports nothing on import, so those low modules can use ``knobs`` without a circle.
"""

"""Click options of ``robustrtk solve`` generated from the configuration tree.

One option per leaf of :data:`~robustrtk.pipeline.config.LEAVES`: the leaf's flag, a
``click.Choice`` of its ``Literal`` choices, ``--x/--no-x`` for booleans, default None (so a
flag not given is told apart from one given with the default value), and help text made of
the leaf's help, the targets it acts in and the defaults of the presets.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import click

from robustrtk.cli.settings import DEFAULT_MODE, TARGETS, acts_in, target_label
from robustrtk.pipeline.config import COOP_PRESET, LEAVES, MODES, PRESETS, Leaf

#: Extra flag names kept for compatibility: ``--smooth`` is ``--smoother``.
ALIASES: dict[str, tuple[str, ...]] = {"smoother": ("--smooth",)}


def format_value(v: Any) -> str:
    """A setting as shown in help and docs: ``3`` for 3.0, ``on``/``off``, ``None``."""
    if isinstance(v, bool):
        return "on" if v else "off"
    if isinstance(v, float):
        return format(v, "g")
    return str(v)


def preset_defaults(key: str) -> list[tuple[str, str]]:
    """``(target label, shown value)`` of leaf ``key`` in each preset it acts in."""
    return [(target_label(*t), format_value(PRESETS[t].get(key))) for t in acts_in(key)]


def defaults_text(key: str, quote: Callable[[str], str] = str) -> str:
    """The presets' defaults: one value when they agree, else ``dpl 0.25; spp 3; ...``."""
    if key == "mode":
        return "; ".join(f"{k.replace('gnss', 'RINEX')} {quote(m)}" for k, m in DEFAULT_MODE.items())
    pairs = preset_defaults(key)
    if not pairs:  # a [coop] leaf: the default of robustrtk coop
        return quote(format_value(COOP_PRESET.get(key))) if key in LEAVES else ""
    if len({v for _, v in pairs}) == 1:
        return quote(pairs[0][1])
    return "; ".join(f"{label} {quote(v)}" for label, v in pairs)


def modes_text(key: str) -> str:
    """The targets a leaf acts in, or ``all`` (before conditions on other settings)."""
    targets = acts_in(key)
    if not targets:
        return ", ".join(LEAVES[key].modes)
    return "all" if targets == TARGETS else ", ".join(target_label(*t) for t in targets)


def help_text(leaf: Leaf) -> str:
    modes = modes_text(leaf.key)
    where = "" if modes == "all" else f" ({modes})"
    return f"{leaf.help}{where} [{defaults_text(leaf.key)}]"


#: The leaves that act in some ``solve`` mode, by key: every leaf but the ``[coop]`` ones
#: (``robustrtk coop``).
SOLVE_LEAVES: dict[str, Leaf] = {k: leaf for k, leaf in LEAVES.items() if set(leaf.modes) & set(MODES)}


def leaf_option(leaf: Leaf) -> Callable[[Callable[..., Any]], Callable[..., Any]]:
    """The click option of one leaf (parameter name = its flat key)."""
    base = leaf.base_type
    if base is bool:
        name = leaf.flag[2:]
        decls = [f"--{name}/--no-{name}", *ALIASES.get(leaf.key, ())]
        return click.option(*decls, leaf.key, default=None, help=help_text(leaf))
    typ: Any = click.Choice(leaf.choices) if leaf.choices else base
    if leaf.flag_value is not None:
        # the flag alone means ``flag_value`` (``--adaptive`` = ``--adaptive state``)
        return click.option(leaf.flag, *ALIASES.get(leaf.key, ()), leaf.key, type=typ, default=None,
                            is_flag=False, flag_value=leaf.flag_value, help=help_text(leaf))  # fmt: skip
    return click.option(leaf.flag, *ALIASES.get(leaf.key, ()), leaf.key, type=typ, default=None,
                        help=help_text(leaf))  # fmt: skip


def config_options(fn: Callable[..., Any]) -> Callable[..., Any]:
    """Decorate a command with one option per config leaf, in tree order."""
    for leaf in reversed(SOLVE_LEAVES.values()):
        fn = leaf_option(leaf)(fn)
    return fn


def config_params() -> list[click.Parameter]:
    """The options of :func:`config_options` as parameter objects, in tree order (as they
    follow a command's own options in its help)."""

    def target() -> None:
        pass

    made: list[click.Parameter] = config_options(target).__click_params__  # type: ignore[attr-defined]
    return made[::-1]


__all__ = ["ALIASES", "SOLVE_LEAVES", "config_options", "config_params", "defaults_text", "format_value",
           "help_text", "leaf_option", "modes_text", "preset_defaults"]  # fmt: skip

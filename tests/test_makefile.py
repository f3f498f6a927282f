"""The Makefile's set-up (benchmarks/README.md, "a fresh clone's make demo"): `make demo`
installs the runtime only, `make test` adds the [test] extra on its own stamp, and the
install falls back to pip when uv cannot be had. Read as text: running make here would
install a whole venv."""

from __future__ import annotations

import re
from conftest import ROOT

MAKEFILE = (ROOT / "Makefile").read_text(encoding="utf-8")


def _rule(target: str) -> tuple[str, str]:
    """The prerequisites and the recipe of ``target``."""
    m = re.search(rf"^{re.escape(target)}:([^\n]*)\n((?:\t[^\n]*\n?)*)", MAKEFILE, re.M)
    assert m is not None, f"no rule for {target}"
    return m.group(1).strip(), m.group(2)


def test_demo_installs_the_runtime_only_and_test_adds_the_test_extra() -> None:
    demo_needs, _ = _rule("demo")
    test_needs, _ = _rule("test")
    _, runtime = _rule("$(STAMP)")
    test_stamp_needs, test_tools = _rule("$(TESTSTAMP)")
    assert demo_needs == "$(STAMP)"
    assert test_needs == "$(TESTSTAMP)" and test_stamp_needs == "$(STAMP)"
    assert "$(call install,-e . pip)" in runtime and "[test]" not in runtime
    assert "$(call install,-e '.[test]')" in test_tools


def test_the_install_uses_uv_and_falls_back_to_pip() -> None:
    install = MAKEFILE.split("\ninstall = ", 1)[1].split("\n\n", 1)[0]
    assert '"$$UV" pip install' in install
    assert install.index('"$$UV" pip install') < install.index("|| {") < install.index("-m pip install")
    assert "ensurepip" in install  # the venv is made without pip; the fallback puts it in first

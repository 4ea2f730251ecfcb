"""The CLI is a thin layer: no command module imports another command module (shared argument
helpers live in rigd/cli/_args.py), and none imports a private name from outside the CLI
(e.g. the model file's `_plain`). Checked on the source, so a new import fails here."""

import ast

from testpaths import ROOT

CLI = ROOT / "rigd" / "cli"


def _imports(path):
    tree = ast.parse(path.read_text(), str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module:
            yield node.lineno, node.module, [a.name for a in node.names]
        elif isinstance(node, ast.Import):
            for a in node.names:
                yield node.lineno, a.name, []


def _violations(path):
    bad = []
    for line, mod, names in _imports(path):
        where = f"{path.name}:{line}"
        if mod.startswith("rigd.cli.") and mod != "rigd.cli._args":
            bad.append(f"{where}: imports command module {mod}")
        if mod == "rigd.cli" and any(n != "_args" for n in names):
            bad.append(f"{where}: imports {names} from rigd.cli")
        if not mod.startswith("rigd.cli") and any(n.startswith("_") and n != "__version__"
                                                  for n in names):
            bad.append(f"{where}: imports private {names} from {mod}")
    return bad


def test_no_command_imports_another_command():
    mods = [p for p in CLI.glob("*.py") if p.name not in ("__init__.py",)]
    assert len(mods) >= 10
    bad = [v for p in mods for v in _violations(p)]
    assert not bad, "\n".join(bad)


def test_the_check_catches_a_forbidden_import(tmp_path):
    p = tmp_path / "compare.py"
    p.write_text("def run(args):\n    from rigd.cli.identify import load_data\n"
                 "    from rigd.ident.modelfile import _plain\n")
    v = _violations(p)
    assert len(v) == 2 and "rigd.cli.identify" in v[0] and "_plain" in v[1]

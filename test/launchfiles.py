"""What the launch files name, read from their syntax trees: launch and launch_ros have no wheels
here, so they cannot be run; every name they hand to ROS is a literal this module finds.

For each ``launch/*.launch.py``: its ``Node(...)`` actions (package, executable, name, the literal
strings of ``arguments``, the keys of every ``parameters`` dict, remappings), the launch arguments
it declares and the ones it reads, the files it joins under a package's share directory
(``PathJoinSubstitution([FindPackageShare(PKG), 'a', 'b'])`` or ``os.path.join(SHARE, 'a', 'b')``
with ``SHARE = get_package_share_directory(PKG)``), and the files it includes with the argument
names it passes. Anything this reader cannot resolve to a literal is a ``problem``, so a launch
file that hides a name from it fails the tests instead of passing unchecked.
"""
from __future__ import annotations

import ast
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LAUNCH_DIR = REPO / "launch"


def launch_paths() -> list[Path]:
    return sorted(LAUNCH_DIR.glob("*.launch.py"))


def text(node: ast.AST | None) -> str | None:
    """The literal string ``node`` is, else None."""
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def called(node: ast.AST) -> str | None:
    """The name a call calls (``Node(...)``, ``launch_ros.actions.Node(...)``: 'Node')."""
    if not isinstance(node, ast.Call):
        return None
    func = node.func
    return func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else None


def keyword(call: ast.Call, name: str) -> ast.AST | None:
    return next((k.value for k in call.keywords if k.arg == name), None)


def first_arg(call: ast.Call, name: str) -> ast.AST | None:
    """A call's first positional argument, or its keyword ``name``."""
    return call.args[0] if call.args else keyword(call, name)


@dataclass
class NodeAction:
    where: str  # file:line
    package: str | None
    executable: str | None
    name: str | None
    arguments: list[str]  # the literal strings among its arguments, in order
    parameters: set[str]  # the keys of its parameters dicts
    remappings: list[tuple[str, str]]


@dataclass
class SharePath:
    where: str
    package: str | None
    parts: list[str | None]  # None: a part that is no literal


@dataclass
class Include:
    where: str
    path: SharePath | None
    arguments: set[str]


@dataclass
class LaunchFile:
    path: Path
    tree: ast.Module
    nodes: list[NodeAction] = field(default_factory=list)
    declared: dict[str, ast.Call] = field(default_factory=dict)  # argument name -> its DeclareLaunchArgument
    read: set[str] = field(default_factory=set)  # launch arguments it reads
    share_paths: list[SharePath] = field(default_factory=list)
    includes: list[Include] = field(default_factory=list)
    options: set[str] = field(default_factory=set)  # every literal starting with '-' (command-line options)
    problems: list[str] = field(default_factory=list)
    constants: dict[str, str] = field(default_factory=dict)  # names bound once, to a string literal

    def literal(self, node: ast.AST | None) -> str | None:
        """The string ``node`` is: a literal, or a name bound once to one (PACKAGE = 'mta_sim_ros')."""
        if isinstance(node, ast.Name):
            return self.constants.get(node.id)
        return text(node)

    def where(self, node: ast.AST) -> str:
        return f"{self.path.name}:{getattr(node, 'lineno', '?')}"


def dict_keys(lf: LaunchFile, node: ast.AST, assigned: dict[str, list[ast.AST]]) -> set[str] | None:
    """The keys of a dict literal, of a name bound to dict literals (and of ``name['key'] = ...``),
    or of ``{**other, 'key': ...}``; None when ``node`` is no dict at all. Keys that are not
    literals are problems."""
    if isinstance(node, ast.Call) and called(node) == "items" and isinstance(node.func, ast.Attribute):
        return dict_keys(lf, node.func.value, assigned)
    if isinstance(node, ast.Name):
        values = [v for v in assigned.get(node.id, []) if isinstance(v, ast.Dict)]
        if not values:
            return None
        keys: set[str] = set()
        for value in values:
            keys |= dict_keys(lf, value, assigned) or set()
        for target in ast.walk(lf.tree):  # overrides['publish_cart_frames'] = False
            if (isinstance(target, ast.Subscript) and isinstance(target.ctx, ast.Store)
                    and isinstance(target.value, ast.Name) and target.value.id == node.id):
                key = text(target.slice)
                if key is None:
                    lf.problems.append(f"{lf.where(target)}: a key of {node.id} that is no literal")
                else:
                    keys.add(key)
        return keys
    if not isinstance(node, ast.Dict):
        return None
    keys = set()
    for key, value in zip(node.keys, node.values):
        if key is None:  # **other
            keys |= dict_keys(lf, value, assigned) or set()
        elif text(key) is None:
            lf.problems.append(f"{lf.where(key)}: a dict key that is no literal")
        else:
            keys.add(text(key))
    return keys


def share_path(lf: LaunchFile, call: ast.Call, shares: dict[str, str]) -> SharePath | None:
    """The package and parts of a path joined under a package's share directory, if ``call`` is one."""
    name = called(call)
    if name == "PathJoinSubstitution":
        items = call.args[0].elts if call.args and isinstance(call.args[0], (ast.List, ast.Tuple)) else None
        if not items or called(items[0]) != "FindPackageShare":
            return None
        package, rest = lf.literal(first_arg(items[0], "package")), items[1:]
    elif name == "join" and call.args:  # os.path.join(SHARE, ...)
        base = call.args[0]
        if isinstance(base, ast.Name) and base.id in shares:
            package = shares[base.id]
        elif called(base) == "get_package_share_directory":
            package = lf.literal(first_arg(base, "package_name"))
        else:
            return None
        rest = call.args[1:]
    else:
        return None
    return SharePath(lf.where(call), package, [lf.literal(p) for p in rest])


def read(path: Path) -> LaunchFile:
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    lf = LaunchFile(path, tree)
    assigned: dict[str, list[ast.AST]] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Assign):
            for target in node.targets:
                if isinstance(target, ast.Name):
                    assigned.setdefault(target.id, []).append(node.value)
    lf.constants = {name: text(values[0]) for name, values in assigned.items()
                    if len(values) == 1 and text(values[0]) is not None}
    shares = {name: lf.literal(first_arg(v, "package_name")) for name, values in assigned.items() for v in values
              if called(v) == "get_package_share_directory"}
    # local helpers that read a launch argument by name: def arg(name): ... LaunchConfiguration(name)
    readers, reader_params = {"LaunchConfiguration"}, set()
    for fn in ast.walk(tree):
        if isinstance(fn, ast.FunctionDef) and fn.args.args:
            param = fn.args.args[0].arg
            if any(called(c) == "LaunchConfiguration" and isinstance(first_arg(c, "variable_name"), ast.Name)
                   and first_arg(c, "variable_name").id == param for c in ast.walk(fn)):
                readers.add(fn.name)
                reader_params.add(param)

    for node in ast.walk(tree):
        if text(node) is not None and text(node).startswith("-") and len(text(node)) > 1:
            lf.options.add(text(node))
        name = called(node)
        if name is None:
            continue
        if name == "Node":
            lf.nodes.append(node_action(lf, node, assigned))
        elif name == "DeclareLaunchArgument":
            arg = text(first_arg(node, "name"))
            if arg is None:
                lf.problems.append(f"{lf.where(node)}: a launch argument whose name is no literal")
            else:
                lf.declared[arg] = node
        elif name in readers:
            arg = first_arg(node, "variable_name")
            if text(arg) is not None:
                lf.read.add(text(arg))
            elif not (name == "LaunchConfiguration" and isinstance(arg, ast.Name) and arg.id in reader_params):
                lf.problems.append(f"{lf.where(node)}: a launch argument read by a name that is no literal")
        elif name == "IncludeLaunchDescription":
            source = first_arg(node, "launch_description_source")
            if called(source) == "PythonLaunchDescriptionSource":
                source = first_arg(source, "launch_file_path")
            path_of = share_path(lf, source, shares) if isinstance(source, ast.Call) else None
            given = keyword(node, "launch_arguments")
            keys = dict_keys(lf, given, assigned) if given is not None else set()
            if path_of is None or keys is None:
                lf.problems.append(f"{lf.where(node)}: an include whose file or arguments are not literals")
            lf.includes.append(Include(lf.where(node), path_of, keys or set()))
        else:
            joined = share_path(lf, node, shares)
            if joined is not None:
                lf.share_paths.append(joined)
    return lf


def node_action(lf: LaunchFile, call: ast.Call, assigned: dict[str, list[ast.AST]]) -> NodeAction:
    parameters: set[str] = set()
    given = keyword(call, "parameters")
    for item in (given.elts if isinstance(given, (ast.List, ast.Tuple)) else [given] if given is not None else []):
        keys = dict_keys(lf, item, assigned)
        if keys is not None:
            parameters |= keys
    arguments = keyword(call, "arguments")
    literal_args = ([text(a) for a in arguments.elts if text(a) is not None]
                    if isinstance(arguments, (ast.List, ast.Tuple)) else [])
    if arguments is not None and not isinstance(arguments, (ast.List, ast.Tuple)):
        lf.problems.append(f"{lf.where(call)}: Node arguments that are no list literal")
    remaps = keyword(call, "remappings")
    remappings = []
    for pair in (remaps.elts if isinstance(remaps, (ast.List, ast.Tuple)) else []):
        if isinstance(pair, ast.Tuple) and len(pair.elts) == 2 and all(text(e) is not None for e in pair.elts):
            remappings.append((text(pair.elts[0]), text(pair.elts[1])))
        else:
            lf.problems.append(f"{lf.where(pair)}: a remapping that is no pair of literals")
    action = NodeAction(lf.where(call), lf.literal(keyword(call, "package")), lf.literal(keyword(call, "executable")),
                        lf.literal(keyword(call, "name")), literal_args, parameters, remappings)
    if action.package is None or action.executable is None:
        lf.problems.append(f"{action.where}: a Node whose package or executable is no literal")
    return action


def read_all() -> dict[str, LaunchFile]:
    return {p.name: read(p) for p in launch_paths()}

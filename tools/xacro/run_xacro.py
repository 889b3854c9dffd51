"""Expands a xacro file with ROS's own xacro and reports any failure on one line.

    python3 run_xacro.py FILE [name:=value]...   the URDF on standard output, exit 0
                                                 (name=value is read as name:=value)
    python3 run_xacro.py --version               which xacro runs, and from where

The xacro is ROS's: the package of a ROS installation when `rospack find xacro` finds one,
else the same package as published on PyPI, installed by scripts/install-deps into the
project's .venv. Both implement ROS 1 Noetic's semantics (in-order processing, Python
expressions, xacro.load_yaml and its unit tags, `^` defaults, scope=, $(arg), $(env),
$(optenv), $(eval), $(dirname), $(find)). $(find pkg) is answered as ROS 1 does, through
rospack over ROS_PACKAGE_PATH; when that does not know the package, the source tree around
the file (the workspace's src folder above the file's package, else the folder holding that
package) is searched as catkin lists packages. Errors: one line "xacro: FILE: message (where)", exit 1.
"""
import os
import subprocess
import sys


def _fail(path, message):
    text = " ".join(str(message).split())
    sys.stderr.write("xacro: %s: %s\n" % (path, text))
    sys.exit(1)


def _ros_xacro_dir():
    """The xacro module's folder of a ROS installation's xacro package, or None."""
    try:
        share = subprocess.run(["rospack", "find", "xacro"], capture_output=True, text=True,
                               timeout=30).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    if not share:
        return None
    prefix = os.path.dirname(os.path.dirname(share))
    for candidate in (os.path.join(share, "src"),  # a source checkout in a workspace
                      os.path.join(prefix, "lib", "python3", "dist-packages"),
                      os.path.join(prefix, "lib", "python3", "site-packages")):
        if os.path.isfile(os.path.join(candidate, "xacro", "__init__.py")):
            return candidate
    return None


def _import_xacro():
    """(module, where it comes from): ROS's installation first, then the PyPI package."""
    ros_dir = _ros_xacro_dir()
    if ros_dir:
        sys.path.insert(0, ros_dir)
    try:
        import xacro
    except ImportError:
        return None, None
    where = "ROS installation" if ros_dir and xacro.__file__.startswith(ros_dir) else "PyPI"
    return xacro, where


def _packages_below(base, depth=4, budget=20000):
    """{name: folder} of the packages in the source tree `base`, as catkin lists them: a
    folder with a package.xml is a package (nothing below it is searched), one with a
    CATKIN_IGNORE is skipped, hidden folders too. Bounded in depth and folders visited."""
    import xml.etree.ElementTree as ET
    found, level = {}, [base]
    for _ in range(depth + 1):
        below = []
        for d in level:
            budget -= 1
            if budget < 0:
                return found
            manifest = os.path.join(d, "package.xml")
            if os.path.isfile(manifest):
                try:
                    name = ET.parse(manifest).getroot().findtext("name")
                except (ET.ParseError, OSError):
                    name = None
                if name:
                    found.setdefault(name.strip(), d)
                continue
            if os.path.exists(os.path.join(d, "CATKIN_IGNORE")):
                continue
            try:
                entries = sorted(os.scandir(d), key=lambda e: e.name)
            except OSError:
                continue
            below += [e.path for e in entries if e.is_dir() and not e.name.startswith(".")]
        level = below
    return found


def _source_tree(top_file):
    """The source tree around top_file: the nearest folder named src above its package (a
    catkin workspace's source space), else the folder holding its package; None without a
    package.xml above the file."""
    d = os.path.dirname(os.path.abspath(top_file))
    while not os.path.isfile(os.path.join(d, "package.xml")):
        if d == os.path.dirname(d):
            return None
        d = os.path.dirname(d)
    package = d
    for _ in range(5):
        d = os.path.dirname(d)
        if os.path.basename(d) == "src":
            return d
        if d == os.path.dirname(d):
            break
    return os.path.dirname(package)


def _package_finder(top_file):
    """$(find pkg): rospack over ROS_PACKAGE_PATH, then the source tree around top_file."""
    import rospkg

    on_path = rospkg.RosPack()
    tree = _source_tree(top_file)
    state = {"near": None}

    def find(pkg):
        try:
            return on_path.get_path(pkg)
        except rospkg.ResourceNotFound:
            pass
        if tree:
            if state["near"] is None:
                state["near"] = _packages_below(tree)
            if pkg in state["near"]:
                return state["near"][pkg]
        raise RuntimeError("$(find %s): package '%s' not found on ROS_PACKAGE_PATH (%s)%s; source "
                           "the workspace's setup.bash or add its src folder to ROS_PACKAGE_PATH"
                           % (pkg, pkg, os.environ.get("ROS_PACKAGE_PATH", "unset"),
                              " nor in " + tree if tree else ""))
    return find


def _give_dirname_its_file(xacro):
    """$(dirname) is the folder of the file being read, as in ROS 1 (whose xacro resolves
    substitutions with roslaunch's, given that file). PyPI's xacro 2.x never puts the file
    into the substitution context, so there $(dirname) always fails: it is given here."""
    context = getattr(xacro, "substitution_args_context", None)
    resolve = getattr(xacro, "eval_extension", None)
    if context is None or resolve is None:
        return

    def eval_extension(s):
        stack = [f for f in (xacro.filestack or []) if f]
        context["filename"] = os.path.abspath(stack[-1]) if stack else None
        return resolve(s)
    xacro.eval_extension = eval_extension


def _message(e):
    """The text of an exception that xacro raised, wrapped or not. Some of xacro's wrappers
    put the wrapped error into their own message as "<class '...'>: text" and then add the
    wrapped error again: that copy is left out."""
    own = str(e.args[0]) if e.args and e.args[0] is not None else ""
    inner = getattr(e, "exc", None)
    suffix = getattr(e, "suffix", None)
    if inner is not None:
        text = _message(inner)
        if isinstance(inner, OSError) and own:
            text = own  # xacro's own words already name the file; the OSError repeats them
        elif own and not own.endswith(": " + str(inner)):
            text = own + " " + text
    else:
        text = str(e) or repr(e)
    return text + (" " + suffix if suffix else "")


def _where(xacro):
    """Where the failure happened: the innermost file and macro, as xacro's own report."""
    parts = []
    files = [f for f in (getattr(xacro, "filestack", None) or []) if f]
    if len(files) > 1:
        parts.append("in " + files[-1])
    macros = getattr(xacro, "macrostack", None) or []
    if macros:
        parts.append("macro " + macros[-1].body.getAttribute("name"))
    return " (" + ", ".join(parts) + ")" if parts else ""


def main(argv):
    if argv[:1] == ["--version"]:
        xacro, where = _import_xacro()
        if xacro is None:
            print("no xacro: run scripts/install-deps")
            return 1
        version = getattr(xacro, "__version__", None)
        if version is None:
            from importlib import metadata
            try:
                version = metadata.version("xacro")
            except metadata.PackageNotFoundError:
                version = "unknown"
        print("xacro %s (%s: %s)" % (version, where, os.path.dirname(xacro.__file__)))
        return 0
    if not argv:
        sys.stderr.write("usage: run_xacro.py FILE [name:=value]...\n")
        return 2
    path, mappings = argv[0], {}
    for a in argv[1:]:
        # name=value too: roslaunch drops a command-line argument holding a second ':='
        name, sep, value = a.partition(":=") if ":=" in a else a.partition("=")
        if not sep or not name:
            sys.stderr.write("xacro: %s: argument '%s' is not name:=value\n" % (path, a))
            return 2
        mappings[name] = value
    xacro, _ = _import_xacro()
    if xacro is None:
        _fail(path, "ROS's xacro is not installed: run scripts/install-deps")
    from xacro import substitution_args
    find = _package_finder(path)
    substitution_args._eval_find = find
    _give_dirname_its_file(xacro)
    if "find" in getattr(substitution_args, "_eval_dict", {}):
        substitution_args._eval_dict["find"] = find
    # xacro's warnings (deprecations, a file's own xacro.warning) go to standard error as it
    # writes them; they are held back until the outcome is known, so that an error stays the
    # one line below.
    import io
    held, stderr = io.StringIO(), sys.stderr
    sys.stderr = held
    try:
        doc = xacro.process_file(path, mappings=mappings)
        text = doc.toprettyxml(indent="  ")
    except Exception as e:  # xacro's own errors, expression errors, YAML, XML, I/O: one line
        import xml.parsers.expat
        sys.stderr = stderr
        msg = _message(e)
        if isinstance(e, xml.parsers.expat.ExpatError):
            msg = "XML parsing error: " + msg
        _fail(path, msg + _where(xacro))
    sys.stderr = stderr
    stderr.write(held.getvalue())
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

#!/usr/bin/env python3
"""Runs every robot description under catkin-style source trees and prints one table.

    scripts/corpus [options] DIR...        (doc/robots.md, "Running a corpus")

A description is a .urdf, .urdf.xacro or .xacro file whose top-level <robot> has, outside
any xacro macro definition, a <link>, a macro call, or an include of such a file: macro-only
and property-only xacro files are skipped. Each is expanded with scripts/xacro (the
arguments a launch file of its package passes, or those DIR/corpus_args.yaml gives) and run
with scripts/simulate for --duration seconds under a timeout. One Markdown table on standard
output: file | arguments | status | cause | links | joints | loops | µs a step.

status: "runs", "refused: LINE" (one line naming what is wrong), or "defect: ..." (a crash,
a hang past the timeout, an internal message, or an error that is not one line). The exit
code is 1 if any description has a defect, 0 otherwise (2 for bad arguments).
"""

import argparse
import concurrent.futures
import glob
import os
import re
import shlex
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# xacro's own elements; any other element of the xacro namespace is a macro call.
XACRO_DIRECTIVES = {"include", "property", "macro", "arg", "if", "unless", "insert_block", "element",
                    "attribute"}
MAX_CONFIGURATIONS = 3  # argument sets taken from launch files, per description

# Messages that come from the implementation rather than from the model: an error line
# that contains one is a defect even when it is one line.
INTERNAL = re.compile(r"Traceback|terminate called|what\(\)|std::|basic_string|vector::|Assertion|"
                      r"is not a function|undefined is not|TypeError|AttributeError|KeyError|"
                      r"NameError|Segmentation|core dumped|internal error|Eigen|nullptr|bad_alloc")


def local(tag):
    return tag.rsplit("}", 1)[-1] if isinstance(tag, str) else ""


def is_xacro(tag):
    return isinstance(tag, str) and tag.startswith("{") and "xacro" in tag[1:tag.index("}")]


# ---------------------------------------------------------------- packages and substitution

def find_packages(roots):
    """package name -> directory, for every package.xml under the roots (first one wins)."""
    packages = {}
    for root in roots:
        for dirpath, dirnames, filenames in os.walk(root):
            dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
            if "package.xml" in filenames:
                try:
                    name = ET.parse(os.path.join(dirpath, "package.xml")).getroot().findtext("name")
                except ET.ParseError:
                    name = None
                if name and name.strip() not in packages:
                    packages[name.strip()] = dirpath
    return packages


def package_of(path, packages):
    """The directory of the package that holds path, or None."""
    d = os.path.dirname(os.path.abspath(path))
    dirs = set(packages.values())
    while d and d != os.path.dirname(d):
        if d in dirs:
            return d
        d = os.path.dirname(d)
    return None


SUBST = re.compile(r"\$\((\w+)((?:\s+[^()\s]+)*)\s*\)")


def substitute(text, args, packages, dirname):
    """roslaunch's $(arg) $(find) $(env) $(optenv) $(dirname) and simple $(eval); None if
    something cannot be resolved."""
    for _ in range(20):
        m = SUBST.search(text)
        if not m:
            return text
        kind, rest = m.group(1), m.group(2).split()
        if kind == "arg" and rest and args.get(rest[0]) is not None:
            value = args[rest[0]]
        elif kind == "find" and rest:
            # a package outside the trees (xacro itself): a path that names no file
            value = packages.get(rest[0], "/nonexistent/" + rest[0])
        elif kind == "env" and rest and rest[0] in os.environ:
            value = os.environ[rest[0]]
        elif kind == "optenv" and rest:
            value = os.environ.get(rest[0], " ".join(rest[1:]))
        elif kind == "dirname":
            value = dirname
        else:
            return None
        text = text[:m.start()] + value + text[m.end():]
    return None


def eval_substitution(text, args):
    """$(eval EXPR) with arg('name'); None if it fails."""
    m = re.search(r"\$\(eval (.*)\)\s*$", text, re.S)
    if not m:
        return text
    try:
        return str(eval(m.group(1), {"__builtins__": {}}, {"arg": lambda n: args[n], "True": True, "False": False}))
    except Exception:
        return None


# ---------------------------------------------------------------- launch-file arguments

def read_launch(launch, given, packages, found, depth=0):
    """Adds to found (file -> [argument lists]) the robot descriptions that launch loads
    with the arguments given to it (roslaunch's $(arg) over the file's own defaults), and
    those of the launch files it includes (one <include> deep: <arg> children and
    pass_all_args)."""
    try:
        root = ET.parse(launch).getroot()
    except (ET.ParseError, OSError):
        return
    here = os.path.dirname(launch)
    args = dict(given)
    for a in root.findall("arg"):  # the file's own; an <include>'s <arg> children are its arguments
        name = a.get("name")
        if name and name not in args:
            args[name] = a.get("value", a.get("default"))
    # defaults may refer to other args
    for _ in range(3):
        for k, v in list(args.items()):
            if v is not None and "$(" in v:
                s = substitute(v, args, packages, here)
                args[k] = eval_substitution(s, args) if s is not None else None
    for p in root.iter("param"):
        name = substitute(p.get("name") or "", args, packages, here)
        command = p.get("command") or p.get("textfile")
        if not (name or "").endswith("robot_description") or not command:
            continue
        command = substitute(command, args, packages, here)
        if command is None:
            continue
        try:
            tokens = shlex.split(command)
        except ValueError:
            continue
        files = [t for t in tokens if re.search(r"\.(urdf|xacro)$", t) and os.path.isfile(t)]
        if not files:
            continue
        xargs = [t for t in tokens if ":=" in t and not t.startswith("-")]
        key = os.path.realpath(files[0])
        found.setdefault(key, [])
        if xargs not in found[key]:
            found[key].append(xargs)
    if depth > 0:
        return
    for inc in root.iter("include"):
        target = substitute(inc.get("file") or "", args, packages, here)
        if not target or not os.path.isfile(target):
            continue
        passed = {k: v for k, v in args.items() if v is not None} if inc.get("pass_all_args") == "true" else {}
        for a in inc.findall("arg"):
            value = a.get("value", a.get("default"))
            value = substitute(value, args, packages, here) if value is not None else None
            if a.get("name") and value is not None:
                passed[a.get("name")] = value
        read_launch(target, passed, packages, found, depth + 1)


def launch_configurations(packages):
    """file -> [argument lists] from <param name=".../robot_description" command=...> of
    every launch file of every package."""
    found = {}
    for pkg_dir in sorted(set(packages.values())):
        for launch in sorted(glob.glob(os.path.join(pkg_dir, "**", "*.launch"), recursive=True)):
            read_launch(launch, {}, packages, found)
    return found


def corpus_args(root, packages):
    """DIR/corpus_args.yaml: {file relative to DIR: "a:=1 b:=2" (roslaunch's $(find) and
    $(env) resolved), a list of such strings (one configuration each), or {skip: reason}
    (a fragment that is not a robot on its own)}. Returns (file -> configurations,
    file -> reason to skip)."""
    path = os.path.join(root, "corpus_args.yaml")
    if not os.path.exists(path):
        return {}, {}
    import yaml
    with open(path) as f:
        data = yaml.safe_load(f) or {}
    configs, skips = {}, {}
    for rel, value in data.items():
        key = os.path.realpath(os.path.join(root, rel))
        if isinstance(value, dict):
            skips[key] = str(value.get("skip", ""))
            continue
        values = value if isinstance(value, list) else [value]
        configs[key] = [shlex.split(substitute(v or "", {}, packages, os.path.dirname(key)) or v or "")
                        for v in values]
    return configs, skips


# ---------------------------------------------------------------- what is a description

def resolve_include(filename, base, packages):
    m = re.match(r"\$\(find ([^)\s]+)\)(.*)$", filename)
    if m:
        return packages[m.group(1)] + m.group(2) if m.group(1) in packages else None
    if "$" in filename:
        return None
    return os.path.normpath(os.path.join(os.path.dirname(base), filename))


def defines_robot(path, packages, seen=None):
    """Whether the file's <robot> has, outside macro definitions, a link, a macro call or an
    include of a file that does."""
    seen = set() if seen is None else seen
    if path in seen or len(seen) > 30:
        return False
    seen.add(path)
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError):
        # malformed or with an undeclared prefix: a description if it has links outside macros
        try:
            text = open(path, errors="replace").read()
        except OSError:
            return False
        text = re.sub(r"<xacro:macro\b.*?</xacro:macro>", "", text, flags=re.S)
        return "<robot" in text and re.search(r"<link\b|<xacro:(?!include|property|arg|if|unless)\w", text) is not None
    if local(root.tag) != "robot":
        return False

    def walk(element):
        for child in element:
            tag = local(child.tag)
            if is_xacro(child.tag):
                if tag == "macro":
                    continue
                if tag in ("if", "unless"):
                    if walk(child):
                        return True
                    continue
                if tag == "include":
                    target = resolve_include(child.get("filename", ""), path, packages)
                    if target and os.path.isfile(target) and defines_robot(target, packages, seen):
                        return True
                    continue
                if tag == "element" and (child.get("{%s}name" % child.tag[1:child.tag.index("}")]) == "link"):
                    return True
                if tag not in XACRO_DIRECTIVES:
                    return True  # a macro call (or xacro:call)
                continue
            if tag == "link":
                return True
        return False

    return walk(root)


def included_files(path, packages):
    """The files a xacro file includes (those whose name can be resolved without args)."""
    try:
        text = open(path, errors="replace").read()
    except OSError:
        return set()
    out = set()
    for m in re.finditer(r"<xacro:include\b[^>]*\bfilename\s*=\s*[\"']([^\"']+)[\"']", text):
        target = resolve_include(m.group(1), path, packages)
        if target:
            out.add(os.path.realpath(target))
    return out


def descriptions(root, packages, launched):
    """Every description under root: files that define a robot, less the fragments other
    files include (unless a launch file names them)."""
    files, included = [], set()
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        for name in sorted(filenames):
            if name.endswith((".urdf", ".xacro")) and ".srdf" not in name:
                path = os.path.join(dirpath, name)
                files.append(path)
                if name.endswith(".xacro"):
                    included |= included_files(path, packages)
    return [p for p in files if (os.path.realpath(p) in launched or os.path.realpath(p) not in included)
            and defines_robot(p, packages)]


# ---------------------------------------------------------------- running one configuration

def one_line(text):
    lines = [l for l in text.replace("\r", "\n").split("\n") if l.strip()]
    return lines


def count_urdf(xml_text):
    """links and joint names of the expanded URDF's <robot>."""
    try:
        root = ET.fromstring(xml_text)
    except ET.ParseError:
        return None, None
    return len(root.findall("link")), [j.get("name") for j in root.findall("joint")]


def classify_error(stage, rc, stderr, timeout):
    """(status, cause) from a failed stage."""
    if rc is None:
        return "defect: hang (no result after %g s)" % timeout, "hang"
    if rc < 0 or rc >= 128:
        sig = -rc if rc < 0 else rc - 128
        return "defect: crash (signal %d)" % sig, "crash"
    lines = one_line(stderr)
    first = lines[0].strip() if lines else "(no message)"
    if not lines:
        return "defect: exit %d with no message" % rc, "no message"
    if INTERNAL.search(stderr):
        return "defect: internal message: " + first, "internal message"
    if len(lines) > 1 and not (stage == "simulate" and rc == 2):
        return "defect: %d-line error: %s" % (len(lines), first), "non-one-line error"
    if stage == "simulate" and rc == 2:
        return "defect: arguments refused: " + first, "arguments"
    return "refused: " + first, cause_of(stage, first)


def cause_of(stage, line):
    """What a refusal is about, from its line."""
    if stage == "xacro" or ": xacro:" in line or line.startswith("xacro:"):
        return "xacro expansion"
    rules = [
        (r"at t = ", "run (failed at t > 0)"),
        (r"joint-space dynamics", "formulation (joint)"),
        (r"without moving any mass", "no mass (kinematic)"),
        (r"inertia", "inertia"),
        (r"does not close|assembl|mirrored", "assembly"),
        (r"\.yaml:\d+:|closed_loop|joint_type|joint_name|name_mot|<loop|<constraint|loop_joint", "loop dialect"),
    ]
    for pattern, cause in rules:
        if re.search(pattern, line, re.I):
            return cause
    return "loader"


def run_configuration(path, xargs, opts, env):
    row = {"links": "", "joints": "", "loops": "", "us": "", "cause": "", "formulation": ""}
    joint_names = None
    if path.endswith(".xacro"):
        try:
            p = subprocess.run([opts.xacro, path] + xargs, capture_output=True, text=True, env=env,
                               timeout=opts.timeout)
            rc, out, err = p.returncode, p.stdout, p.stderr
        except subprocess.TimeoutExpired:
            rc, out, err = None, "", ""
        if rc != 0:
            row["status"], row["cause"] = classify_error("xacro", rc, err, opts.timeout)
            if row["cause"] == "hang":
                row["cause"] = "xacro hang"
            return row
        xml_text = out
    else:
        with open(path, errors="replace") as f:
            xml_text = f.read()
    links, joint_names = count_urdf(xml_text)
    if links is not None:
        row["links"], row["joints"] = links, len(joint_names)
    if links == 0:
        row["status"] = "not a robot"  # transmissions or gazebo elements only
        return row
    if opts.expand_only:
        row["status"] = "expands"
        return row
    with tempfile.TemporaryDirectory() as tmp:
        csv = os.path.join(tmp, "run.csv")
        cmd = [opts.simulate, path] + xargs + ["--duration", str(opts.duration), "--output-every", "1000000000",
                                               "--csv", csv, "--reactions"]
        try:
            p = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=opts.timeout)
            rc, err = p.returncode, p.stderr
        except subprocess.TimeoutExpired:
            rc, err = None, ""
        if rc != 0:
            row["status"], row["cause"] = classify_error("simulate", rc, err, opts.timeout)
            return row
        row["status"] = "runs"
        m = re.search(r"(\d+) steps of \S+ s in ([0-9.]+) s wall", err)
        if m and int(m.group(1)) > 0:
            us = float(m.group(2)) / int(m.group(1)) * 1e6
            row["us"] = "%.1f" % us if us < 10 else "%.0f" % us
        m = re.search(r"formulation: (joint|absolute) coordinates", err)
        row["formulation"] = m.group(1) if m else ""
        # loops: the joints with reactions that are not joints of the URDF (loop closures of
        # every dialect: simulate names each one)
        try:
            with open(csv) as f:
                header = f.readline().strip().split(",")
            reacting = {c.rsplit(".", 1)[0] for c in header if c.endswith(".fx")}
            row["loops"] = len(reacting - set(joint_names or []))
        except OSError:
            pass
        if INTERNAL.search(err):
            line = next(l for l in one_line(err) if INTERNAL.search(l))
            row["status"], row["cause"] = "defect: internal message: " + line.strip(), "internal message"
    return row


# ---------------------------------------------------------------- main

def main():
    parser = argparse.ArgumentParser(prog="scripts/corpus", description=__doc__.split("\n\n")[0])
    parser.add_argument("dirs", nargs="+", metavar="DIR", help="catkin-style source trees")
    parser.add_argument("--duration", type=float, default=2.0, help="simulated seconds (2)")
    parser.add_argument("--timeout", type=float, default=120.0, help="seconds for each expansion and run (120)")
    parser.add_argument("--jobs", type=int, default=1, help="descriptions run at once (1)")
    parser.add_argument("--only", default="", help="only files whose path contains this text")
    parser.add_argument("--list", action="store_true", help="list the descriptions and their arguments, run none")
    parser.add_argument("--expand-only", action="store_true", help="expand the xacro files, run none")
    parser.add_argument("--simulate", default=os.path.join(REPO, "scripts", "simulate"), help="simulate program")
    parser.add_argument("--xacro", default=os.path.join(REPO, "scripts", "xacro"), help="xacro program")
    opts = parser.parse_args()
    roots = [os.path.abspath(d) for d in opts.dirs]
    for d in roots:
        if not os.path.isdir(d):
            parser.error("%s: not a directory" % d)

    packages = find_packages(roots)
    env = dict(os.environ)
    env["ROS_PACKAGE_PATH"] = ":".join(roots + [p for p in [os.environ.get("ROS_PACKAGE_PATH")] if p])
    launched = launch_configurations(packages)
    jobs = []  # (label, path, args, source)
    skipped = []  # (label, reason)
    for root in roots:
        given, skips = corpus_args(root, packages)
        for path in descriptions(root, packages, launched):
            label = os.path.relpath(path, root)
            if opts.only and opts.only not in label:
                continue
            key = os.path.realpath(path)
            if key in skips:
                skipped.append((label, "corpus_args.yaml: " + skips[key]))
                continue
            if key in given:
                configs, source = given[key], "corpus_args.yaml"
            elif key in launched:
                configs, source = launched[key][:MAX_CONFIGURATIONS], "launch"
            else:
                configs, source = [[]], ""
            for xargs in configs:
                jobs.append((label, path, xargs, source))

    if opts.list:
        for label, _, xargs, source in jobs:
            print("%s %s%s" % (label, " ".join(shlex.quote(a) for a in xargs), "  (%s)" % source if source else ""))
        return 0

    def work(job):
        label, path, xargs, _ = job
        row = run_configuration(path, xargs, opts, env)
        print("%-70s %s" % (label[-70:], row["status"][:100]), file=sys.stderr, flush=True)
        return row

    with concurrent.futures.ThreadPoolExecutor(max_workers=max(1, opts.jobs)) as pool:
        rows = list(pool.map(work, jobs))

    by_length = sorted(packages.items(), key=lambda kv: -len(kv[1]))

    def shown(xargs):
        """The arguments as a user writes them: package paths as $(find pkg)."""
        out = []
        for a in xargs:
            for name, d in by_length:
                a = a.replace(d + "/", "$(find %s)/" % name)
            out.append(shlex.quote(a) if re.search(r"\s", a) else a)
        return " ".join(out)

    def cell(text):
        return str(text).replace("|", "\\|").replace("\n", " ")

    print("| file | arguments | status | cause | links | joints | loops | µs a step | coordinates |")
    print("|---|---|---|---|---|---|---|---|---|")
    for (label, _, xargs, _), row in zip(jobs, rows):
        if row["status"] == "not a robot":
            skipped.append((label + (" " + " ".join(xargs) if xargs else ""), "no <link> after expansion"))
            continue
        print("| %s | %s | %s | %s | %s | %s | %s | %s | %s |" % (
            cell(label), cell(shown(xargs)), cell(row["status"]), cell(row["cause"]), row["links"],
            row["joints"], row["loops"], row["us"], row["formulation"]))
    runs = sum(r["status"] == "runs" for r in rows)
    refused = sum(r["status"].startswith("refused") for r in rows)
    defects = sum(r["status"].startswith("defect") for r in rows)
    expands = sum(r["status"] == "expands" for r in rows)
    print("\n%d configurations: %d run, %s%d refused, %d defects" % (
        runs + refused + defects + expands, runs, "%d expand, " % expands if opts.expand_only else "", refused, defects))
    if skipped:
        print("\nNot descriptions (%d): %s" % (len(skipped), "; ".join("%s (%s)" % s for s in skipped)))
    return 1 if defects else 0


if __name__ == "__main__":
    sys.exit(main())

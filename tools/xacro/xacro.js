#!/usr/bin/env node
// Expands a xacro file to URDF on standard output (doc/xacro.md):
//   node xacro.js FILE [name:=value]...
// The expansion is the npm package xacro-parser (ROS Jade+ rules: in order, xacro: prefix
// required, local properties) over @xmldom/xmldom; this script only reads files, answers
// $(find), $(env) and $(optenv), and reports. A FILE not ending in .xacro is copied to
// standard output unchanged (so launch files can run any model through it).
// Errors: one line on standard error, "xacro: FILE: what is wrong"; exit code 1 (2: usage).
'use strict';
const fs = require('fs');
const path = require('path');
const { execFileSync } = require('child_process');
let DOMParser, XMLSerializer, XacroParser;
try {
  ({ DOMParser, XMLSerializer } = require('@xmldom/xmldom'));
  ({ XacroParser } = require('xacro-parser'));
} catch (e) {
  process.stderr.write(`xacro: ${process.argv[2] || ''}: the npm packages are not installed in ${__dirname}/node_modules: run scripts/install-deps\n`);
  process.exit(1);
}

const USAGE = 'usage: xacro.js FILE [name:=value]...';

class XacroError extends Error {}

// The file whose XML xmldom is reading now (the top file or an include), for messages.
let parsing = null;
let includeFailure = null;       // why the last include could not be read or parsed
let substitutionFailure = null;  // why the last $(...) failed
let xmlFailure = null;           // the XML error xmldom wraps in its ParseError

// The XML of `parsing` (the file it came from), checked before xacro-parser sees it:
// XML errors with file and line, and what xacro-parser would silently get wrong.
function parseXml(text) {
  xmlFailure = null;
  let doc;
  try {
    doc = new global.DOMParser().parseFromString(text, 'text/xml');
  } catch (e) {
    throw xmlFailure || e;
  }
  // xacro-parser evaluates ${xacro.load_yaml(...)} to nothing, without an error
  if (/\$\{[^}]*load_yaml\s*\(/.test(text)) throw new XacroError(`${parsing}: xacro.load_yaml() is not supported (doc/xacro.md)`);
  return doc;
}

// xacro-parser calls `new DOMParser().parseFromString(text, 'text/xml')`: the xmldom one,
// made to stop at the first error, not only at fatal ones.
global.DOMParser = class extends DOMParser {
  constructor() {
    super({
      onError(level, message, context) {
        if (level === 'warning') return;
        const loc = context && context.locator;
        const line = loc && loc.lineNumber ? `:${loc.lineNumber}` : '';
        xmlFailure = new XacroError(`${parsing}${line}: XML: ${String(message).split('\n')[0]}`);
        throw xmlFailure;
      },
    });
  }
};

// The directory of a ROS package: `rospack find`, else a search of ROS_PACKAGE_PATH
// (package.xml <name>, not descending into packages or CATKIN_IGNOREd directories).
function findPackage(name) {
  try {
    const out = execFileSync('rospack', ['find', name], { encoding: 'utf8', timeout: 20000, stdio: ['ignore', 'pipe', 'pipe'] });
    if (out.trim()) return out.trim();
  } catch (e) {
    if (e.code !== 'ENOENT') throw new XacroError(`$(find ${name}): rospack cannot find package '${name}' (ROS_PACKAGE_PATH=${process.env.ROS_PACKAGE_PATH || ''})`);
  }
  const search = (dir, depth) => {
    const manifest = path.join(dir, 'package.xml');
    if (fs.existsSync(manifest)) {
      const m = /<name>\s*([^<\s]+)\s*<\/name>/.exec(fs.readFileSync(manifest, 'utf8'));
      return m && m[1] === name ? dir : null;
    }
    if (depth > 8 || fs.existsSync(path.join(dir, 'CATKIN_IGNORE'))) return null;
    let entries = [];
    try { entries = fs.readdirSync(dir, { withFileTypes: true }); } catch (e) { return null; }
    for (const e of entries) {
      if (!e.isDirectory() || e.name.startsWith('.')) continue;
      const found = search(path.join(dir, e.name), depth + 1);
      if (found) return found;
    }
    return null;
  };
  for (const root of (process.env.ROS_PACKAGE_PATH || '').split(':').filter(Boolean)) {
    const found = search(root, 0);
    if (found) return found;
  }
  throw new XacroError(`$(find ${name}): no package '${name}' on ROS_PACKAGE_PATH (${process.env.ROS_PACKAGE_PATH || 'unset'})`);
}

// $(...) substitutions other than $(arg), which xacro-parser answers itself.
function substitution(command, ...args) {
  try {
    return answer(command, ...args);
  } catch (e) {
    substitutionFailure = e.message;
    throw e;
  }
}

function answer(command, ...args) {
  switch (command) {
    case 'arg':
      return undefined;
    case 'find':
      return findPackage(args[0]);
    case 'env':
      if (process.env[args[0]] === undefined) throw new XacroError(`$(env ${args[0]}): environment variable '${args[0]}' is not set`);
      return process.env[args[0]];
    case 'optenv':
      return process.env[args[0]] !== undefined ? process.env[args[0]] : args.slice(1).join(' ');
    default:
      throw new XacroError(`$(${[command, ...args].join(' ')}): substitution '${command}' is not supported (doc/xacro.md)`);
  }
}

// xacro-parser's messages run over several lines, each "XacroParser: ...": one line.
function oneLine(message) {
  return String(message).split('\n')
    .map(s => s.replace(/^XacroParser:\s*/, '').trim().replace(/\.$/, ''))
    .filter(s => s && !/^Cannot run rospack command/.test(s))
    .map(s => s.replace(/^Failed to process expression (".*")\s*$/, 'in $1'))
    .join(': ');
}

async function main(argv) {
  if (argv.length === 0 || argv[0] === '-h' || argv[0] === '--help') {
    (argv.length ? process.stdout : process.stderr).write(USAGE + '\n');
    return argv.length ? 0 : 2;
  }
  const file = argv[0];
  const args = {};
  for (const a of argv.slice(1)) {
    // name=value too: roslaunch's command line takes no ':=' inside an argument's value
    const m = /^([A-Za-z_][A-Za-z0-9_]*):?=(.*)$/s.exec(a);
    if (!m) {
      process.stderr.write(`xacro: ${file}: argument '${a}' is not name:=value\n${USAGE}\n`);
      return 2;
    }
    args[m[1]] = m[2];
  }
  let text;
  try {
    text = fs.readFileSync(file, 'utf8');
  } catch (e) {
    process.stderr.write(`xacro: ${file}: cannot read the file (${e.code || e.message})\n`);
    return 1;
  }
  if (!file.endsWith('.xacro')) {
    if (Object.keys(args).length) {
      process.stderr.write(`xacro: ${file}: name:=value arguments given, but the file is not a .xacro file\n`);
      return 1;
    }
    process.stdout.write(text);
    return 0;
  }
  const parser = new XacroParser();
  parser.inOrder = true;
  parser.requirePrefix = true;
  parser.localProperties = true;
  parser.workingPath = path.dirname(path.resolve(file)) + '/';
  parser.arguments = args;
  parser.rospackCommands = substitution;
  parser.getFileContents = async p => {
    const included = path.normalize(p);
    let content;
    try {
      content = fs.readFileSync(included, 'utf8');
      // parse once here so that a broken include is reported with its own error
      parsing = included;
      parseXml(content);
    } catch (e) {
      includeFailure = e instanceof XacroError ? e.message : `${included}: cannot read the included file (${e.code || e.message})`;
      throw e;
    }
    return content;
  };
  let urdf;
  try {
    parsing = file;
    // the top file's XML errors first, with its line
    parseXml(text);
    const doc = await parser.parse(text);
    urdf = new XMLSerializer().serializeToString(doc);
  } catch (e) {
    // XML errors name their file and line; the others are about the top file
    let message = oneLine(e.message);
    if (e instanceof XacroError) message = e.message;
    else if (/Could not load included file/.test(message) && includeFailure) message = `${file}: include: ${includeFailure}`;
    else if (substitutionFailure && message.includes(substitutionFailure)) message = `${file}: ${substitutionFailure}`;
    else message = `${file}: ${message}`;
    process.stderr.write(`xacro: ${oneLine(message)}\n`);
    return 1;
  }
  if (!/^\s*<robot[\s>]/.test(urdf)) {
    process.stderr.write(`xacro: ${file}: the expansion has no <robot> root element\n`);
    return 1;
  }
  process.stdout.write(`<?xml version="1.0"?>\n<!-- expanded from ${path.basename(file).replace(/--/g, '- -')} by xacro-parser (mechanism_sim tools/xacro) -->\n${urdf}\n`);
  return 0;
}

main(process.argv.slice(2)).then(code => { process.exitCode = code; }, e => {
  process.stderr.write(`xacro: ${process.argv[2] || ''}: ${oneLine(e && e.message)}\n`);
  process.exitCode = 1;
});

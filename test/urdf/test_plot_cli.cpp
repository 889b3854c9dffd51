// scripts/plot as a user runs it: the PNG it writes, the --summary JSON, --columns, errors.
#include <gtest/gtest.h>

#include "run_command.h"

#include <sys/stat.h>
#include <sys/wait.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

const std::string kSource = MECHANISM_SIM_SOURCE_DIR;
const std::string kPlot = kSource + "/scripts/plot";

struct Result {
  int code;
  std::string out;  // stdout
  std::string err;  // stderr
};

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

Result run(const std::string& args) {
  const std::string err_file = ::testing::TempDir() + "/plot_stderr.txt";
  const auto r = mechanism_sim::testing_util::runCommand(kPlot + " " + args + " 2>" + err_file);
  return {r.code, r.out, slurp(err_file)};
}

void write(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}

// ---- just enough JSON to read the summary
struct Json {
  enum Kind { Null, Bool, Number, String, Array, Object } kind = Null;
  double num = 0;
  bool b = false;
  std::string str;
  std::vector<Json> arr;
  std::map<std::string, Json> obj;

  const Json& operator[](const std::string& key) const {
    static const Json missing;
    auto it = obj.find(key);
    return it == obj.end() ? missing : it->second;
  }
  const Json& operator[](size_t i) const { return arr.at(i); }
  bool has(const std::string& key) const { return obj.count(key) > 0; }
};

class JsonParser {
 public:
  explicit JsonParser(const std::string& s) : s_(s) {}
  Json parse() {
    Json v = value();
    ws();
    if (i_ != s_.size()) throw std::runtime_error("trailing text at " + std::to_string(i_));
    return v;
  }

 private:
  void ws() {
    while (i_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[i_]))) ++i_;
  }
  char peek() {
    ws();
    if (i_ >= s_.size()) throw std::runtime_error("unexpected end");
    return s_[i_];
  }
  void expect(char c) {
    if (peek() != c) throw std::runtime_error(std::string("expected ") + c + " at " + std::to_string(i_));
    ++i_;
  }
  bool literal(const char* w) {
    const std::string word(w);
    if (s_.compare(i_, word.size(), word) != 0) return false;
    i_ += word.size();
    return true;
  }
  std::string string() {
    expect('"');
    std::string r;
    while (i_ < s_.size() && s_[i_] != '"') {
      char c = s_[i_++];
      if (c == '\\') {
        const char e = s_.at(i_++);
        switch (e) {
          case 'n': r += '\n'; break;
          case 't': r += '\t'; break;
          case 'r': r += '\r'; break;
          case 'b': r += '\b'; break;
          case 'f': r += '\f'; break;
          case 'u': r += '?'; i_ += 4; break;  // not needed here
          default: r += e;
        }
      } else {
        r += c;
      }
    }
    expect('"');
    return r;
  }
  Json value() {
    Json v;
    const char c = peek();
    if (c == '{') {
      v.kind = Json::Object;
      ++i_;
      if (peek() == '}') return ++i_, v;
      for (;;) {
        std::string k = string();
        expect(':');
        v.obj[k] = value();
        if (peek() == ',') { ++i_; continue; }
        expect('}');
        return v;
      }
    }
    if (c == '[') {
      v.kind = Json::Array;
      ++i_;
      if (peek() == ']') return ++i_, v;
      for (;;) {
        v.arr.push_back(value());
        if (peek() == ',') { ++i_; continue; }
        expect(']');
        return v;
      }
    }
    if (c == '"') {
      v.kind = Json::String;
      v.str = string();
      return v;
    }
    if (literal("true")) { v.kind = Json::Bool; v.b = true; return v; }
    if (literal("false")) { v.kind = Json::Bool; return v; }
    if (literal("null")) return v;
    size_t used = 0;
    v.num = std::stod(s_.substr(i_, 40), &used);
    v.kind = Json::Number;
    i_ += used;
    return v;
  }
  const std::string& s_;
  size_t i_ = 0;
};

Json parseJson(const std::string& s) { return JsonParser(s).parse(); }

std::vector<std::string> strings(const Json& a) {
  std::vector<std::string> r;
  for (const auto& e : a.arr) r.push_back(e.str);
  return r;
}

const Json* panel(const Json& summary, const std::string& name) {
  for (const auto& p : summary["panels"].arr)
    if (p["name"].str == name) return &p;
  return nullptr;
}

// A run with known values: two dofs, a sine of amplitude 2.5 sampled at its peaks, a constant
// effort, reaction components making |f| = 5 exactly, and a violation that is 0 at times.
const std::vector<std::string> kHeader = {
    "time", "crank_joint.position", "crank_joint.velocity", "crank_joint.effort", "slider_joint.position",
    "slider_joint.velocity", "slider_joint.effort", "pin.fx", "pin.fy", "pin.fz", "constraint.position",
    "constraint.velocity", "base.x"};
constexpr int kRows = 1001;
constexpr double kPi = 3.14159265358979323846;

std::string knownCsv() {
  std::ostringstream s;
  s.precision(17);
  for (size_t i = 0; i < kHeader.size(); ++i) s << (i ? "," : "") << kHeader[i];
  s << "\n";
  for (int i = 0; i < kRows; ++i) {
    const double t = i / 1000.0;  // 0 .. 1 s; sin peaks at t = 0.25 and 0.75 exactly
    const double pos = i == 250 ? 2.5 : i == 750 ? -2.5 : 2.5 * std::sin(2 * kPi * t);
    s << t << "," << pos << "," << 5 * kPi * std::cos(2 * kPi * t) << "," << -1.25 << ","
      << 0.1 * t << "," << 0.1 << "," << (i == 400 ? 7.0 : 0.0) << "," << 3.0 << "," << -4.0 << ",0,"
      << (i % 3 == 0 ? 0.0 : 1e-14 * (1 + i % 5)) << "," << 2e-13 << "," << 0.5 << "\n";
  }
  return s.str();
}

class PlotCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = ::testing::TempDir() + "/plot_cli";
    mkdir(dir_.c_str(), 0755);
    csv_ = dir_ + "/run.csv";
    write(csv_, knownCsv());
  }
  std::string dir_, csv_;
};

TEST_F(PlotCli, DrawsThePanelsAndSummarisesEveryRow) {
  const std::string png = dir_ + "/out.png";
  std::remove(png.c_str());
  const Result r = run(csv_ + " -o " + png + " --summary --title 'my model'");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err, "");

  const std::string img = slurp(png);
  ASSERT_GT(img.size(), 5000u);
  EXPECT_EQ(img.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));

  const Json s = parseJson(r.out);
  EXPECT_EQ(s["output"].str, png);
  EXPECT_EQ(s["samples"].num, kRows);
  EXPECT_NEAR(s["time"]["first"].num, 0.0, 1e-12);
  EXPECT_NEAR(s["time"]["last"].num, 1.0, 1e-12);
  EXPECT_EQ(s["title"].str.rfind("my model\nrun.csv: 1 s, 1001 samples", 0), 0u) << s["title"].str;
  EXPECT_NE(s["title"].str.find("peak |effort| 7 (slider_joint, t = 0.4 s)"), std::string::npos) << s["title"].str;

  std::vector<std::string> names;
  for (const auto& p : s["panels"].arr) names.push_back(p["name"].str);
  EXPECT_EQ(names, (std::vector<std::string>{"position", "velocity", "effort", "reaction force",
                                             "constraint violation"}));
  EXPECT_EQ(strings((*panel(s, "position"))["columns"]),
            (std::vector<std::string>{"crank_joint.position", "slider_joint.position"}));
  EXPECT_EQ(strings((*panel(s, "reaction force"))["columns"]), (std::vector<std::string>{"pin.fx", "pin.fy", "pin.fz"}));
  const Json& force_line = (*panel(s, "reaction force"))["lines"][0];
  EXPECT_EQ(force_line["label"].str, "pin |f|");
  EXPECT_NEAR(force_line["min"].num, 5.0, 1e-9);
  EXPECT_NEAR(force_line["max"].num, 5.0, 1e-9);
  EXPECT_TRUE((*panel(s, "constraint violation"))["log"].b);
  EXPECT_FALSE((*panel(s, "position"))["log"].b);
  EXPECT_EQ(strings(s["unplotted"]), std::vector<std::string>{"base.x"});  // link poses: only on request

  const Json& c = s["columns"];
  EXPECT_NEAR(c["crank_joint.position"]["min"].num, -2.5, 1e-9);
  EXPECT_NEAR(c["crank_joint.position"]["max"].num, 2.5, 1e-9);
  EXPECT_NEAR(c["crank_joint.velocity"]["max"].num, 5 * kPi, 1e-9);
  EXPECT_NEAR(c["crank_joint.effort"]["min"].num, -1.25, 1e-9);
  EXPECT_NEAR(c["slider_joint.position"]["max"].num, 0.1, 1e-9);
  EXPECT_NEAR(c["slider_joint.effort"]["max"].num, 7.0, 1e-9);
  EXPECT_NEAR(c["constraint.position"]["min"].num, 0.0, 1e-20);
  EXPECT_NEAR(c["constraint.position"]["max"].num, 5e-14, 1e-22);
  EXPECT_NEAR(s["max_position_violation"].num, 5e-14, 1e-22);
  EXPECT_FALSE(c.has("base.x"));
}

TEST_F(PlotCli, DefaultOutputIsBesideTheCsv) {
  const std::string png = dir_ + "/run.png";
  std::remove(png.c_str());
  ASSERT_EQ(run(csv_).code, 0);
  EXPECT_EQ(slurp(png).substr(0, 4), "\x89PNG");
}

TEST_F(PlotCli, ColumnsPicksASubsetAndGroupsItBySuffix) {
  const Result r =
      run(csv_ + " -o " + dir_ + "/sub.png --summary --columns 'crank_joint.*,slider_joint.position,base.x,pin.fx'");
  ASSERT_EQ(r.code, 0) << r.err;
  const Json s = parseJson(r.out);
  std::vector<std::string> names;
  for (const auto& p : s["panels"].arr) names.push_back(p["name"].str);
  EXPECT_EQ(names, (std::vector<std::string>{"position", "velocity", "effort", "reaction force", "other"}));
  EXPECT_EQ(strings((*panel(s, "position"))["columns"]),
            (std::vector<std::string>{"crank_joint.position", "slider_joint.position"}));
  EXPECT_EQ(strings((*panel(s, "velocity"))["columns"]), std::vector<std::string>{"crank_joint.velocity"});
  EXPECT_EQ(strings((*panel(s, "other"))["columns"]), std::vector<std::string>{"base.x"});
  EXPECT_EQ((*panel(s, "reaction force"))["lines"][0]["label"].str, "pin.fx");  // a component alone, no |f|
  EXPECT_EQ(s["columns"].obj.size(), 6u);
  EXPECT_NEAR(s["columns"]["base.x"]["max"].num, 0.5, 1e-9);
  EXPECT_EQ(s["samples"].num, kRows);
}

void expectOneLineError(const Result& r, const std::string& needle) {
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_EQ(r.out, "");
  EXPECT_EQ(r.err.rfind("plot: ", 0), 0u) << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
}

TEST_F(PlotCli, ErrorsAreOneLineAndExitCode2) {
  const std::string png = " -o " + dir_ + "/err.png";
  expectOneLineError(run(dir_ + "/missing.csv" + png), "missing.csv: no such file");
  expectOneLineError(run(dir_ + png), "is a directory");

  write(dir_ + "/empty.csv", "");
  expectOneLineError(run(dir_ + "/empty.csv" + png), "empty.csv: empty file");
  write(dir_ + "/header_only.csv", "time,a.position\n");
  expectOneLineError(run(dir_ + "/header_only.csv" + png), "no data rows");
  write(dir_ + "/no_time.csv", "t,a.position\n0,1\n");
  expectOneLineError(run(dir_ + "/no_time.csv" + png), "no 'time' column");
  write(dir_ + "/bad_cell.csv", "time,a.position,a.velocity\n0,1,2\n0.1,1,abc\n");
  expectOneLineError(run(dir_ + "/bad_cell.csv" + png), "line 3, column 3 'a.velocity': 'abc' is not a number");
  write(dir_ + "/ragged.csv", "time,a.position\n0,1\n0.1\n");
  expectOneLineError(run(dir_ + "/ragged.csv" + png), "line 3 has 1 cell, the header has 2");

  expectOneLineError(run(csv_ + png + " --columns nope.position"), "unknown column 'nope.position'");
  expectOneLineError(run(csv_ + png + " --columns 'crank_joint.*,zz*'"), "'zz*' matches no column");
  expectOneLineError(run(csv_ + png + " --frobnicate"), "--frobnicate");
  expectOneLineError(run(""), "RUN.csv");
}

}  // namespace

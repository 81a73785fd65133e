/// @brief A strict parser of the Prometheus text exposition format (0.0.4) for tests: every line
/// must be a valid HELP, TYPE or sample line, families contiguous with TYPE before samples,
/// histogram buckets cumulative with +Inf equal to _count.
#ifndef SCULPT_TESTS_INTEGRATION_PROMETHEUS_TEXT_H_
#define SCULPT_TESTS_INTEGRATION_PROMETHEUS_TEXT_H_

#include <cmath>
#include <cstdlib>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

namespace sculpt::testing {

struct PromSample {
  std::string name;
  std::map<std::string, std::string> labels;
  double value = 0;
};

struct PromPage {
  std::map<std::string, std::string> types;  // family -> counter | gauge | histogram | ...
  std::vector<PromSample> samples;
  /// The value of the sample with this name and exactly these labels; NaN when absent.
  double Value(const std::string& name, const std::map<std::string, std::string>& labels = {}) const {
    for (const PromSample& s : samples) {
      if (s.name == name && s.labels == labels) return s.value;
    }
    return std::nan("");
  }
};

/// Parses `text`; on the first violation returns false with the line number and reason.
inline bool ParsePrometheusText(const std::string& text, PromPage* page, std::string* error) {
  static const std::regex kName("[a-zA-Z_:][a-zA-Z0-9_:]*");
  static const std::regex kLabelName("[a-zA-Z_][a-zA-Z0-9_]*");
  auto fail = [&](int line, const std::string& why) {
    *error = "line " + std::to_string(line) + ": " + why;
    return false;
  };
  auto parse_value = [](const std::string& s, double* v) {
    if (s == "+Inf") return *v = INFINITY, true;
    if (s == "-Inf") return *v = -INFINITY, true;
    if (s == "NaN") return *v = NAN, true;
    if (s.empty()) return false;
    char* end = nullptr;
    *v = std::strtod(s.c_str(), &end);
    return end == s.c_str() + s.size();
  };
  // The family a sample belongs to: histogram samples carry a suffix.
  auto family_of = [&](const std::string& name) {
    for (const char* suffix : {"_bucket", "_sum", "_count"}) {
      const std::string sfx(suffix);
      if (name.size() > sfx.size() && name.compare(name.size() - sfx.size(), sfx.size(), sfx) == 0) {
        const std::string base = name.substr(0, name.size() - sfx.size());
        auto it = page->types.find(base);
        if (it != page->types.end() && (it->second == "histogram" || it->second == "summary")) {
          return base;
        }
      }
    }
    return name;
  };
  if (!text.empty() && text.back() != '\n') return fail(0, "the page does not end in a newline");
  std::set<std::string> finished;  // families whose block has ended
  std::string current;
  std::set<std::string> helped;
  std::istringstream in(text);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.empty()) return fail(n, "empty line");
    if (line[0] == '#') {
      std::istringstream ls(line);
      std::string hash, kind, name;
      ls >> hash >> kind >> name;
      if (hash != "#" || (kind != "HELP" && kind != "TYPE")) return fail(n, "bad comment: " + line);
      if (!std::regex_match(name, kName)) return fail(n, "bad metric name: " + name);
      if (name != current) {
        if (finished.count(name)) return fail(n, "family " + name + " is not contiguous");
        if (!current.empty()) finished.insert(current);
        current = name;
      }
      if (kind == "HELP") {
        if (!helped.insert(name).second) return fail(n, "second HELP for " + name);
      } else {
        std::string type, extra;
        ls >> type;
        if (ls >> extra) return fail(n, "junk after TYPE: " + line);
        static const std::set<std::string> kTypes = {"counter", "gauge", "histogram", "summary",
                                                     "untyped"};
        if (!kTypes.count(type)) return fail(n, "bad type: " + type);
        if (page->types.count(name)) return fail(n, "second TYPE for " + name);
        page->types[name] = type;
      }
      continue;
    }
    PromSample s;
    size_t i = 0;
    while (i < line.size() && line[i] != '{' && line[i] != ' ') ++i;
    s.name = line.substr(0, i);
    if (!std::regex_match(s.name, kName)) return fail(n, "bad sample name: " + s.name);
    if (i < line.size() && line[i] == '{') {
      ++i;
      while (i < line.size() && line[i] != '}') {
        size_t eq = line.find('=', i);
        if (eq == std::string::npos) return fail(n, "label without '='");
        const std::string lname = line.substr(i, eq - i);
        if (!std::regex_match(lname, kLabelName)) return fail(n, "bad label name: " + lname);
        if (eq + 1 >= line.size() || line[eq + 1] != '"') return fail(n, "unquoted label value");
        std::string value;
        size_t j = eq + 2;
        for (; j < line.size() && line[j] != '"'; ++j) {
          if (line[j] == '\\') {
            if (j + 1 >= line.size()) return fail(n, "dangling escape");
            const char e = line[++j];
            if (e == 'n') value += '\n';
            else if (e == '\\' || e == '"') value += e;
            else return fail(n, "bad escape");
          } else {
            value += line[j];
          }
        }
        if (j >= line.size()) return fail(n, "unterminated label value");
        if (!s.labels.emplace(lname, value).second) return fail(n, "repeated label " + lname);
        i = j + 1;
        if (i < line.size() && line[i] == ',') ++i;
      }
      if (i >= line.size()) return fail(n, "unterminated label set");
      ++i;
    }
    if (i >= line.size() || line[i] != ' ') return fail(n, "no space before the value");
    std::string rest = line.substr(i + 1);
    const size_t sp = rest.find(' ');
    const std::string value_text = rest.substr(0, sp);
    if (!parse_value(value_text, &s.value)) return fail(n, "bad value: " + value_text);
    if (sp != std::string::npos) {
      const std::string ts = rest.substr(sp + 1);
      if (ts.empty() || ts.find_first_not_of("-0123456789") != std::string::npos) {
        return fail(n, "bad timestamp: " + ts);
      }
    }
    const std::string family = family_of(s.name);
    if (!page->types.count(family)) return fail(n, "sample before its TYPE: " + s.name);
    if (family != current) return fail(n, "sample " + s.name + " outside its family's block");
    const std::string& type = page->types[family];
    if (type == "counter" && (s.value < 0 || std::isnan(s.value))) {
      return fail(n, "negative or NaN counter " + s.name);
    }
    if (type == "histogram" && s.name == family) return fail(n, "bare histogram sample");
    if (s.name.size() > family.size() && s.name.substr(family.size()) == "_bucket" &&
        !s.labels.count("le")) {
      return fail(n, "bucket without le");
    }
    page->samples.push_back(std::move(s));
  }
  // Histograms: buckets non-decreasing in le order, +Inf present and equal to _count.
  for (const auto& [family, type] : page->types) {
    if (type != "histogram") continue;
    std::map<std::map<std::string, std::string>, std::vector<std::pair<double, double>>> series;
    std::map<std::map<std::string, std::string>, double> counts;
    for (const PromSample& s : page->samples) {
      if (s.name == family + "_bucket") {
        auto labels = s.labels;
        double le = 0;
        parse_value(labels["le"], &le);
        labels.erase("le");
        series[labels].push_back({le, s.value});
      } else if (s.name == family + "_count") {
        counts[s.labels] = s.value;
      }
    }
    for (auto& [labels, buckets] : series) {
      double last_le = -INFINITY, last = 0;
      for (const auto& [le, v] : buckets) {
        if (!(le > last_le)) return fail(0, family + ": buckets not in increasing le order");
        if (v < last) return fail(0, family + ": buckets not cumulative");
        last_le = le;
        last = v;
      }
      if (!std::isinf(last_le)) return fail(0, family + ": no +Inf bucket");
      if (!counts.count(labels) || counts[labels] != last) {
        return fail(0, family + ": +Inf bucket differs from _count");
      }
    }
  }
  return true;
}

}  // namespace sculpt::testing

#endif  // SCULPT_TESTS_INTEGRATION_PROMETHEUS_TEXT_H_

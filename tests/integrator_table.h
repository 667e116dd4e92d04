// The integrator table of docs/integrators.md (the rows under its heading
// "Integrators"), read back so tests can hold it to the registry (what
// `obscura integrators` prints). Header-only: used by
// test_docs_consistency.cpp (built-ins) and plugin_tests.cpp (the bent-normal
// plugin's row).
//
// Row format: | `name` [(plugin)] | what it estimates | parameters |
// The parameters cell names each parameter as a backticked word outside any
// parentheses, optionally followed by "(... default V ...)"; backticked words
// inside parentheses are values. Outside parentheses, "every `X` parameter"
// takes all of integrator X's parameters, a backticked `--option` is a CLI
// option, and the name of another integrator is a reference.
#pragma once

#include <algorithm>
#include <cstdlib>
#include <set>
#include <string>
#include <vector>

#include <obscura/integrator.h>

namespace obscura::test {

struct IntegratorTableParam {
  std::string name;
  std::string stated;  // the default the row states ("" when it states none)
};

struct IntegratorTableRow {
  int line = 0;  // 1-based line in the document
  std::string name;
  bool plugin = false;
  std::vector<IntegratorTableParam> params;    // backticked words outside parentheses, in order
  std::vector<std::string> inherits;  // X of "every `X` parameter"
};

// Splits a table line on '|' that are not escaped as "\|".
inline std::vector<std::string> tableCells(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  for (size_t i = 0; i < line.size(); ++i) {
    if (line[i] == '|' && (i == 0 || line[i - 1] != '\\')) {
      cells.push_back(cell);
      cell.clear();
    } else {
      cell += line[i];
    }
  }
  cells.push_back(cell);
  // "| a | b |" gives "", " a ", " b ", "": drop the outer empties.
  if (!cells.empty() && cells.front().find_first_not_of(' ') == std::string::npos) cells.erase(cells.begin());
  if (!cells.empty() && cells.back().find_first_not_of(' ') == std::string::npos) cells.pop_back();
  return cells;
}

// The value after "default " in a parenthetical: a backticked word, or the
// text up to a space, comma, semicolon or ')'. U+2212 (minus) reads as '-'.
inline std::string statedDefault(const std::string& paren) {
  const size_t at = paren.find("default ");
  if (at == std::string::npos) return "";
  size_t i = at + 8;
  std::string v;
  if (i < paren.size() && paren[i] == '`') {
    const size_t end = paren.find('`', i + 1);
    v = paren.substr(i + 1, end == std::string::npos ? std::string::npos : end - i - 1);
  } else {
    while (i < paren.size() && std::string(" ,;)").find(paren[i]) == std::string::npos) v += paren[i++];
  }
  for (size_t p; (p = v.find("\xe2\x88\x92")) != std::string::npos;) v.replace(p, 3, "-");
  return v;
}

// The path the table lives at, relative to the source tree (for messages).
inline constexpr const char* kIntegratorTableDoc = "docs/integrators.md";

// The rows of the table under the heading "Integrators" (any level: "#",
// "##", ...), up to the next heading.
inline std::vector<IntegratorTableRow> integratorTableRows(const std::string& readme) {
  std::vector<IntegratorTableRow> rows;
  bool inSection = false;
  int lineNo = 0;
  size_t start = 0;
  while (start < readme.size()) {
    size_t end = readme.find('\n', start);
    if (end == std::string::npos) end = readme.size();
    const std::string line = readme.substr(start, end - start);
    start = end + 1;
    ++lineNo;
    if (!line.empty() && line[0] == '#') {
      const size_t text = line.find_first_not_of('#');
      inSection = text != std::string::npos && line.compare(text, std::string::npos, " Integrators") == 0;
      continue;
    }
    if (!inSection || line.rfind("| `", 0) != 0) continue;
    const std::vector<std::string> cells = tableCells(line);
    if (cells.size() != 3) continue;
    IntegratorTableRow row;
    row.line = lineNo;
    const std::string& nameCell = cells[0];
    const size_t a = nameCell.find('`'), b = nameCell.find('`', a + 1);
    row.name = nameCell.substr(a + 1, b - a - 1);
    row.plugin = nameCell.find("(plugin)") != std::string::npos;
    const std::string& p = cells[2];
    int depth = 0;
    for (size_t i = 0; i < p.size(); ++i) {
      if (p[i] == '(') ++depth;
      if (p[i] == ')') depth = std::max(0, depth - 1);
      if (p[i] != '`') continue;
      const size_t close = p.find('`', i + 1);
      if (close == std::string::npos) break;
      const std::string word = p.substr(i + 1, close - i - 1);
      const bool every = i >= 6 && p.compare(i - 6, 6, "every ") == 0 && p.compare(close + 1, 10, " parameter") == 0;
      i = close;
      if (depth > 0 || word.rfind("--", 0) == 0) continue;
      if (every) {
        row.inherits.push_back(word);
        continue;
      }
      IntegratorTableParam param{word, ""};
      size_t j = close + 1;
      while (j < p.size() && p[j] == ' ') ++j;
      if (j < p.size() && p[j] == '(') {  // its parenthetical, to the matching ')'
        int d = 0;
        size_t k = j;
        for (; k < p.size(); ++k) {
          if (p[k] == '(') ++d;
          if (p[k] == ')' && --d == 0) break;
        }
        param.stated = statedDefault(p.substr(j + 1, k - j - 1));
      }
      row.params.push_back(param);
    }
    rows.push_back(row);
  }
  return rows;
}

// Two defaults agree when equal as text or as numbers ("1" and "1.0").
inline bool defaultsAgree(const std::string& stated, const std::string& declared) {
  if (stated == declared) return true;
  char *e1 = nullptr, *e2 = nullptr;
  const double x = std::strtod(stated.c_str(), &e1), y = std::strtod(declared.c_str(), &e2);
  return !stated.empty() && !declared.empty() && *e1 == '\0' && *e2 == '\0' && x == y;
}

// Every disagreement between a row and the descriptor it documents, one line
// each ("docs/integrators.md:LINE: ..."). `known` resolves "every `X` parameter" and
// tells references to other integrators from parameter names.
inline std::vector<std::string> integratorRowProblems(const IntegratorTableRow& row, const IntegratorDescriptor& d,
                                                  const std::vector<IntegratorDescriptor>& known) {
  std::vector<std::string> problems;
  const std::string where = std::string(kIntegratorTableDoc) + ":" + std::to_string(row.line) + ": `" + row.name + "`: ";
  const auto findKnown = [&](const std::string& name) -> const IntegratorDescriptor* {
    for (const IntegratorDescriptor& k : known)
      if (k.name == name) return &k;
    return nullptr;
  };
  const auto declared = [&](const std::string& name) -> const ParamSpec* {
    for (const ParamSpec& s : d.params)
      if (s.name == name) return &s;
    return nullptr;
  };
  std::multiset<std::string> named;
  for (const std::string& x : row.inherits) {
    const IntegratorDescriptor* other = findKnown(x);
    if (!other) {
      problems.push_back(where + "\"every `" + x + "` parameter\" names no registered integrator");
      continue;
    }
    for (const ParamSpec& s : other->params) {
      named.insert(s.name);
      const ParamSpec* mine = declared(s.name);
      if (!mine)
        problems.push_back(where + "inherits `" + s.name + "` from `" + x + "`, which is not one of its parameters");
      else if (mine->defaultValue != s.defaultValue)
        problems.push_back(where + "inherits `" + s.name + "` from `" + x + "` but its default is " +
                           mine->defaultValue + ", not " + s.defaultValue);
    }
  }
  for (const IntegratorTableParam& p : row.params) {
    const ParamSpec* s = declared(p.name);
    if (!s) {
      if (p.name != row.name && findKnown(p.name)) continue;  // a reference ("as for `obscurance`")
      problems.push_back(where + "names `" + p.name + "`, which is not one of its parameters");
      continue;
    }
    named.insert(p.name);
    if (!p.stated.empty() && !defaultsAgree(p.stated, s->defaultValue))
      problems.push_back(where + "states `" + p.name + "` default " + p.stated + ", the registry says " +
                         s->defaultValue);
  }
  for (const ParamSpec& s : d.params) {
    const size_t n = named.count(s.name);
    if (n == 0) problems.push_back(where + "does not name its parameter `" + s.name + "`");
    if (n > 1) problems.push_back(where + "names `" + s.name + "` " + std::to_string(n) + " times");
  }
  return problems;
}

}  // namespace obscura::test

// The documentation against the code it describes:
// - docs/integrators.md's integrator table against the registry (`obscura
//   integrators` prints the registry, so this keeps the two in step): every
//   built-in has a row naming exactly its parameters, with the defaults it
//   states equal to the declared ones, and every row names a registered
//   integrator (rows marked "(plugin)" are checked in plugin_tests.cpp
//   against the plugin).
// - docs/cli.md names every option the CLI's help prints.
// - Citations: every document under docs/ that a source or document
//   mentions exists, every `docs/math.md §N` names a section docs/math.md has,
//   every section cited by name (README or docs/<file>.md followed by the name
//   in double quotes) is a heading of that file, and no file cites the design
//   notes that lived outside the repository.
// - README.md is a front door: at most 300 lines.
// - docs/exr.md's list of the layer names --pass refuses is the code's list.
// - The Python hints (setup.sh's closing line, docs/python.md) run the
//   interpreter the module is built for, not whichever python3 PATH finds.
#include <gtest/gtest.h>

#include <cctype>
#include <cstdio>
#include <map>
#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <obscura/integrator.h>
#include "app/render_setup.h"
#include "tests/integrator_table.h"
#include "tests/support.h"

namespace obscura::test {
namespace {

namespace fs = std::filesystem;

std::string readFile(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(DocsConsistency, IntegratorTableMatchesTheRegistry) {
  const std::string doc = kIntegratorTableDoc;
  const std::vector<IntegratorTableRow> rows = integratorTableRows(readFile(fs::path(sourceDir()) / doc));
  ASSERT_FALSE(rows.empty()) << "no rows under the heading \"Integrators\" in " << doc;
  const std::vector<IntegratorDescriptor>& all = IntegratorRegistry::instance().all();
  std::set<std::string> documented;
  for (const IntegratorTableRow& row : rows) {
    EXPECT_TRUE(documented.insert(row.name).second) << doc << ":" << row.line << ": second row for " << row.name;
    const IntegratorDescriptor* d = nullptr;
    for (const IntegratorDescriptor& x : all)
      if (x.name == row.name) d = &x;
    if (row.plugin) {
      EXPECT_EQ(d, nullptr) << doc << ":" << row.line << ": " << row.name << " is marked (plugin) but built in";
      continue;
    }
    if (!d) {
      ADD_FAILURE() << doc << ":" << row.line << ": `" << row.name << "` is not a registered integrator";
      continue;
    }
    for (const std::string& p : integratorRowProblems(row, *d, all)) ADD_FAILURE() << p;
  }
  for (const IntegratorDescriptor& d : all)
    EXPECT_TRUE(documented.count(d.name)) << doc << "'s integrator table has no row for `" << d.name << "`";
}

// The check itself, on a made-up table: it must see a wrong default, a
// missing and an unknown parameter, a duplicate, and read inheritance,
// references, CLI options, escaped bars and U+2212 minus signs.
TEST(DocsConsistency, TableCheckSeesEveryKindOfDisagreement) {
  // ao's first two parameters, distance (inf) and rays (1), as the fixture
  // (its own list goes on: the lobe controls).
  IntegratorDescriptor ao = IntegratorRegistry::instance().find("ao");
  ao.params.resize(2);
  ASSERT_EQ(ao.params[0].name, "distance");
  ASSERT_EQ(ao.params[1].name, "rays");
  const std::vector<IntegratorDescriptor>& all = IntegratorRegistry::instance().all();
  const auto problems = [&](const std::string& paramsCell) {
    const std::string text = "## Integrators\n\n| name | what | parameters |\n|---|---|---|\n| `ao` | x (a\\|b) | " +
                             paramsCell + " |\n\n## Next\n| `ao` | not | read |\n";
    const auto rows = integratorTableRows(text);
    EXPECT_EQ(rows.size(), 1u);
    return rows.empty() ? std::vector<std::string>{"no row"} : integratorRowProblems(rows[0], ao, all);
  };
  EXPECT_TRUE(problems("`distance` (R, `inf` or a number, default `inf`), `rays` (default 1)").empty());
  EXPECT_TRUE(problems("`distance` (default inf; see `--sky`), `rays` as for `obscurance`").empty());
  const auto has = [](const std::vector<std::string>& v, const std::string& needle) {
    for (const std::string& s : v)
      if (s.find(needle) != std::string::npos) return true;
    return false;
  };
  EXPECT_TRUE(has(problems("`distance` (default `inf`), `rays` (default 2)"), "states `rays` default 2"));
  EXPECT_TRUE(has(problems("`distance` (default \xe2\x88\x92" "1), `rays`"), "states `distance` default -1"));
  EXPECT_TRUE(has(problems("`distance`"), "does not name its parameter `rays`"));
  EXPECT_TRUE(has(problems("`distance`, `rays`, `spread` (default 3)"), "names `spread`"));
  EXPECT_TRUE(has(problems("`distance`, `rays`, `rays`"), "names `rays` 2 times"));
  EXPECT_TRUE(has(problems("every `nonesuch` parameter, `distance`, `rays`"), "names no registered integrator"));
  // "every `obscurance` parameter" brings falloff, sigma and estimator, which
  // ao does not have, and distance and rays, which it has with those defaults.
  const auto inherited = problems("every `obscurance` parameter");
  EXPECT_TRUE(has(inherited, "inherits `falloff` from `obscurance`, which is not one of its parameters"));
  EXPECT_FALSE(has(inherited, "`rays`"));
}

// Text files of the source tree (no build trees, no hidden directories).
std::vector<fs::path> sourceFiles() {
  std::vector<fs::path> files;
  const std::set<std::string> text = {".cpp", ".h", ".md", ".txt", ".cmake", ".py", ".sh", ".in", ".json"};
  const fs::path root(sourceDir());
  for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator(); ++it) {
    const std::string name = it->path().filename().string();
    if (it->is_directory()) {
      if (name.empty() || name[0] == '.' || name.rfind("build", 0) == 0 || name == "out") it.disable_recursion_pending();
      continue;
    }
    if (it->is_regular_file() && (text.count(it->path().extension().string()) || name == "run"))
      files.push_back(it->path());
  }
  return files;
}

// Section numbers docs/math.md has ("## N. title").
std::set<int> mathSections() {
  std::set<int> s;
  std::istringstream in(readFile(fs::path(sourceDir()) / "docs" / "math.md"));
  for (std::string line; std::getline(in, line);)
    if (line.rfind("## ", 0) == 0 && line.size() > 3 && std::isdigit(static_cast<unsigned char>(line[3])))
      s.insert(std::stoi(line.substr(3)));
  return s;
}

TEST(DocsConsistency, CitedDocumentsAndSectionsExist) {
  const fs::path root(sourceDir());
  const std::set<int> sections = mathSections();
  ASSERT_FALSE(sections.empty()) << "docs/math.md has no numbered sections";
  const std::regex doc(R"(docs/[A-Za-z0-9_./-]+\.md)");
  // "docs/math.md §4", "§4–5", "§4-5", "§4 and §5", "§1, §2", "section 4"
  const std::regex cite(R"(docs/math\.md,? (?:§|sections? )(\d+)(?:\s*(?:–|-|and|,)\s*§?(\d+))?)");
  for (const fs::path& file : sourceFiles()) {
    const std::string text = readFile(file);
    const std::string rel = fs::relative(file, root).string();
    for (auto m = std::sregex_iterator(text.begin(), text.end(), doc); m != std::sregex_iterator(); ++m) {
      std::string target = m->str();
      while (!target.empty() && target.back() == '.') target.pop_back();
      EXPECT_TRUE(fs::exists(root / target)) << rel << " cites " << target << ", which does not exist";
    }
    for (auto m = std::sregex_iterator(text.begin(), text.end(), cite); m != std::sregex_iterator(); ++m) {
      for (size_t g = 1; g <= 2; ++g) {
        if (!(*m)[g].matched) continue;
        const int n = std::stoi((*m)[g].str());
        EXPECT_TRUE(sections.count(n)) << rel << " cites docs/math.md section " << n << ", which it does not have";
      }
    }
  }
}

// EXPECTED TO FAIL until the lead rewrites the old citations: the design
// notes MATH and ARCHITECTURE lived outside the repository and are replaced
// by docs/math.md (same section numbers) and docs/architecture.md. A source
// citing them points at nothing a reader of the repository has.
TEST(DocsConsistency, NoCitationOfTheOldDesignNotes) {
  const fs::path root(sourceDir());
  // Built from pieces so this file does not cite them itself.
  const std::vector<std::string> old = {std::string("MATH") + ".md", std::string("ARCHITECTURE") + ".md"};
  for (const fs::path& file : sourceFiles()) {
    std::istringstream in(readFile(file));
    int lineNo = 0;
    for (std::string line; std::getline(in, line);) {
      ++lineNo;
      for (const std::string& o : old)
        if (line.find(o) != std::string::npos)
          ADD_FAILURE() << fs::relative(file, root).string() << ":" << lineNo << " cites " << o
                        << " (use docs/math.md §N or docs/architecture.md)";
    }
  }
}

// --- Citations of sections by name ------------------------------------------

// The names a document's sections can be cited by: its headings ("#" to
// "######", outside fenced code blocks), and the bold run-in titles of its
// paragraphs and list items ("**Depth.**", "**Symmetric taps**"), without a
// final period.
std::set<std::string> citableSections(const std::string& text) {
  std::set<std::string> names;
  std::istringstream in(text);
  bool fenced = false;
  const std::regex bold(R"(\*\*([^*]+?)\.?\*\*)");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("```", 0) == 0) {
      fenced = !fenced;
      continue;
    }
    if (fenced) continue;
    const size_t hashes = line.find_first_not_of('#');
    if (hashes > 0 && hashes <= 6 && hashes != std::string::npos && line[hashes] == ' ') {
      std::string name = line.substr(hashes + 1);
      while (!name.empty() && (name.back() == ' ' || name.back() == '\r')) name.pop_back();
      names.insert(name);
    }
    for (auto m = std::sregex_iterator(line.begin(), line.end(), bold); m != std::sregex_iterator(); ++m)
      names.insert((*m)[1].str());
  }
  return names;
}

struct SectionCitation {
  std::string document;  // "README.md" or a document under docs/
  std::string section;   // the quoted name, its line breaks and comment leaders folded into spaces
  int line = 0;
};

// Every citation of a section by name in a text: README or docs/<file>.md, a
// space, then the name in double quotes (also escaped, as in a C++ string).
// A name may run over a line break, where the next line's comment leader
// (//, #, *) and indentation are dropped.
std::vector<SectionCitation> sectionCitations(const std::string& text) {
  std::vector<SectionCitation> out;
  // Built from pieces so this file does not cite anything itself.
  const std::regex cite(std::string("(README|docs/[A-Za-z0-9_./-]+\\.md) \\\\?") + "\"([^\"\\\\]{1,200})\\\\?\"");
  const std::regex fold(R"(\s*\n\s*(//+|#+|\*+)?\s*)");
  for (auto m = std::sregex_iterator(text.begin(), text.end(), cite); m != std::sregex_iterator(); ++m) {
    SectionCitation c;
    c.document = (*m)[1].str() == "README" ? "README.md" : (*m)[1].str();
    c.section = std::regex_replace((*m)[2].str(), fold, " ");
    c.line = 1 + int(std::count(text.begin(), text.begin() + m->position(0), '\n'));
    out.push_back(c);
  }
  return out;
}

TEST(DocsConsistency, CitedSectionsAreHeadingsOfTheirDocument) {
  const fs::path root(sourceDir());
  std::map<std::string, std::set<std::string>> sections;  // by document
  int checked = 0;
  for (const fs::path& file : sourceFiles()) {
    const std::string rel = fs::relative(file, root).string();
    for (const SectionCitation& c : sectionCitations(readFile(file))) {
      if (!sections.count(c.document)) {
        if (!fs::exists(root / c.document)) {
          ADD_FAILURE() << rel << ":" << c.line << " cites " << c.document << " \"" << c.section
                        << "\", but " << c.document << " does not exist";
          continue;
        }
        sections[c.document] = citableSections(readFile(root / c.document));
      }
      ++checked;
      EXPECT_TRUE(sections[c.document].count(c.section))
          << rel << ":" << c.line << " cites " << c.document << " \"" << c.section << "\", which is not a heading of "
          << c.document;
    }
  }
  EXPECT_GT(checked, 50) << "found too few section citations: is the pattern still right?";
}

// The check itself, on made-up text: names over line breaks, escaped quotes,
// headings of every level, bold titles, fenced code left out.
TEST(DocsConsistency, SectionCitationCheckReadsWhatItShould) {
  const std::string q = "\"";
  const std::string text = std::string("// see ") + "READ" + "ME " + q + "Depth\n// and camera conventions" + q +
                           "\nhelp(\"(docs/x" + ".md \\" + q + "Adaptive sampling\\" + q + ")\")\n# docs/y" + ".md " + q +
                           "A\n# B" + q;
  const std::vector<SectionCitation> c = sectionCitations(text);
  ASSERT_EQ(c.size(), 3u);
  EXPECT_EQ(c[0].document, "README.md");
  EXPECT_EQ(c[0].section, "Depth and camera conventions");
  EXPECT_EQ(c[0].line, 1);
  EXPECT_EQ(c[1].document, std::string("docs/x") + ".md");
  EXPECT_EQ(c[1].section, "Adaptive sampling");
  EXPECT_EQ(c[2].section, "A B");
  const std::set<std::string> s =
      citableSections("# Title\n## Two words\n### Deep one\n```sh\n# not a heading\n```\n- **Depth.** d = 1/Z\n**Bold** x\n");
  EXPECT_TRUE(s.count("Title") && s.count("Two words") && s.count("Deep one") && s.count("Depth") && s.count("Bold"));
  EXPECT_FALSE(s.count("not a heading"));
}

// --- docs/cli.md against the CLI's help --------------------------------------

// stdout and stderr of `obscura ARGS`.
std::string runObscura(const std::string& args) {
  const std::string cmd = std::string("'") + obscuraBinary() + "' " + args + " 2>&1";
  std::string out;
  if (FILE* p = ::popen(cmd.c_str(), "r")) {
    char buf[4096];
    for (size_t n; (n = std::fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
    ::pclose(p);
  }
  return out;
}

// Every option a CLI11 help text shows: `--long` words anywhere, and `-x`
// short flags where a word starts with one.
std::set<std::string> helpOptions(const std::string& help) {
  std::set<std::string> options;
  const std::regex opt(R"((^|[\s,\[(])(--[A-Za-z][A-Za-z0-9-]*|-[A-Za-z])(?=[\s,=\])]|$))");
  for (auto m = std::sregex_iterator(help.begin(), help.end(), opt); m != std::sregex_iterator(); ++m)
    options.insert((*m)[2].str());
  return options;
}

// The subcommands the top-level help lists (CLI11: "Subcommands:", or
// "SUBCOMMANDS:" in other versions, then one indented name a line).
std::vector<std::string> helpSubcommands(const std::string& help) {
  std::vector<std::string> subs;
  size_t at = help.find("Subcommands:");
  if (at == std::string::npos) at = help.find("SUBCOMMANDS:");
  if (at == std::string::npos) return subs;
  std::istringstream in(help.substr(at + 12));
  const std::regex sub(R"(^\s+([a-z][a-z-]*)(\s|$).*)");
  for (std::string line; std::getline(in, line);) {
    std::smatch m;
    if (std::regex_match(line, m, sub)) subs.push_back(m[1].str());
    else if (!line.empty() && line.find_first_not_of(' ') != std::string::npos && line[0] != ' ') break;
  }
  return subs;
}

// The option as a word of the text: not part of a longer option.
bool mentionsOption(const std::string& text, const std::string& option) {
  const std::regex word("(^|[^A-Za-z0-9-])" + option + "([^A-Za-z0-9-]|$)");
  return std::regex_search(text, word);
}

TEST(DocsConsistency, CliDocNamesEveryOptionTheHelpPrints) {
  const std::string doc = readFile(fs::path(sourceDir()) / "docs" / "cli.md");
  ASSERT_FALSE(doc.empty()) << "docs/cli.md is missing";
  const std::string top = runObscura("--help");
  const std::vector<std::string> subs = helpSubcommands(top);
  ASSERT_GE(subs.size(), 5u) << "obscura --help lists too few subcommands:\n" << top;
  std::vector<std::pair<std::string, std::string>> helps = {{"", top}};
  for (const std::string& s : subs) {
    EXPECT_TRUE(mentionsOption(doc, "obscura " + s)) << "docs/cli.md has no synopsis of `obscura " << s << "`";
    helps.emplace_back(s, runObscura(s + " --help"));
  }
  for (const auto& [sub, help] : helps) {
    const std::set<std::string> options = helpOptions(help);
    EXPECT_FALSE(options.empty()) << "obscura " << sub << " --help printed no options:\n" << help;
    for (const std::string& o : options)
      EXPECT_TRUE(mentionsOption(doc, o)) << "docs/cli.md does not mention `" << o << "`, which `obscura "
                                           << (sub.empty() ? "" : sub + " ") << "--help` prints";
  }
}

// The check itself: what it reads from a help text and what counts as a
// mention.
TEST(DocsConsistency, HelpOptionReadingSeesLongAndShortOptions) {
  const std::set<std::string> o = helpOptions(
      "OPTIONS:\n  -h,--help   Print this\n  -o,--output TEXT REQUIRED  out\n  --min-spp INT  (but see --background-spp)\n"
      "  --shutter TEXT  e.g. -0.25,0.25; non-EXR\n");
  EXPECT_EQ(o, (std::set<std::string>{"-h", "--help", "-o", "--output", "--min-spp", "--background-spp", "--shutter"}));
  EXPECT_TRUE(mentionsOption("`--spp` and `-o OUT`", "--spp"));
  EXPECT_FALSE(mentionsOption("`--spp-max`", "--spp"));
  EXPECT_TRUE(mentionsOption("`-o OUT`", "-o"));
  EXPECT_FALSE(mentionsOption("--output", "-o"));
  EXPECT_EQ(helpSubcommands("X\nSUBCOMMANDS:\n  render   Render\n  info     Describe\n"),
            (std::vector<std::string>{"render", "info"}));
  EXPECT_EQ(helpSubcommands("Options:\n  -h,--help  Help\n\nSubcommands:\n  merge  Merge\n"),
            (std::vector<std::string>{"merge"}));
}

// --- The README stays a front door -------------------------------------------

TEST(DocsConsistency, ReadmeIsAtMost300Lines) {
  const std::string readme = readFile(fs::path(sourceDir()) / "README.md");
  ASSERT_FALSE(readme.empty());
  const long lines = std::count(readme.begin(), readme.end(), '\n') + (readme.back() == '\n' ? 0 : 1);
  EXPECT_LE(lines, 300) << "README.md has " << lines
                        << " lines: it is the front door; move reference material into docs/ (README \"Documentation\")";
}

// --- The reserved layer names ------------------------------------------------

// docs/exr.md "Layer names --pass refuses" lists, in its bullets, every name
// reservedLayerNames() holds (a prefix written `Name*`) and no other.
TEST(DocsConsistency, ReservedLayerNamesMatchTheCode) {
  const std::string doc = readFile(fs::path(sourceDir()) / "docs" / "exr.md");
  const std::string heading = "\n## Layer names --pass refuses\n";
  const size_t from = doc.find(heading);
  ASSERT_NE(from, std::string::npos) << "docs/exr.md has no heading \"Layer names --pass refuses\"";
  const size_t to = doc.find("\n## ", from + heading.size());
  std::istringstream in(doc.substr(from, to == std::string::npos ? std::string::npos : to - from));
  std::set<std::string> documented;
  const std::regex name("`([A-Za-z][A-Za-z0-9_]*\\*?)`");
  std::string line;
  bool inList = false;
  while (std::getline(in, line)) {
    if (line.rfind("- ", 0) == 0) inList = true;
    else if (line.empty() || line.rfind("  ", 0) != 0) inList = false;  // a bullet's continuation is indented
    if (!inList) continue;
    for (std::sregex_iterator it(line.begin(), line.end(), name), end; it != end; ++it) documented.insert((*it)[1]);
  }
  std::set<std::string> code;
  for (const ReservedLayerName& r : reservedLayerNames()) code.insert(std::string(r.name) + (r.prefix ? "*" : ""));
  EXPECT_EQ(documented, code);
  EXPECT_GE(code.size(), size_t(40));
}

// --- The Python hints name the interpreter the module is built for -------------

// setup.sh builds the module for Debian's /usr/bin/python3 (its NumPy is the
// one python3-numpy installs); a hint saying `python3` runs whichever comes
// first in PATH (pyenv's, a venv's), which cannot import it or lacks NumPy.
// Every line of setup.sh and docs/python.md that imports the module or sets
// PYTHONPATH must name setup.sh's interpreter.
TEST(DocsConsistency, PythonHintsNameTheInterpreterSetupBuildsFor) {
  const fs::path root(sourceDir());
  const std::string setup = readFile(root / "scripts" / "setup.sh");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(setup, m, std::regex("\\npython_exe=(\\S+)\\n"))) << "scripts/setup.sh sets no python_exe=";
  const std::string exe = m[1];
  EXPECT_EQ(exe, "/usr/bin/python3");
  EXPECT_NE(setup.find("-DPython_EXECUTABLE=$python_exe"), std::string::npos) << "setup.sh builds for another interpreter";
  int hints = 0;
  for (const char* file : {"scripts/setup.sh", "docs/python.md"}) {
    std::istringstream in(readFile(root / file));
    std::string line;
    for (int n = 1; std::getline(in, line); ++n) {
      const bool runs = line.find("PYTHONPATH=") != std::string::npos || line.find("-c 'import obscura'") != std::string::npos ||
                        line.find("-c \"import obscura\"") != std::string::npos;
      if (!runs || line.find("<prefix>") != std::string::npos) continue;  // the install-prefix note names no command
      ++hints;
      // The interpreter is the word after PYTHONPATH=... (or the first word).
      const bool named = line.find(" " + exe + " ") != std::string::npos || line.find("$python_exe ") != std::string::npos ||
                         line.rfind(exe + " ", 0) == 0;
      EXPECT_TRUE(named) << file << ":" << n << " runs Python without naming " << exe << ": " << line;
    }
  }
  EXPECT_GE(hints, 3);  // setup.sh's closing hint and docs/python.md's examples
}

}  // namespace
}  // namespace obscura::test

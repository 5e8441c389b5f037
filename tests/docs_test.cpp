// The documents the repository cites are the documents it holds: every Markdown file a source,
// script or document names exists, no file cites the seed notes the project started from (they
// live outside the repository), every "CONTRACT.md §N" names a section CONTRACT.md has,
// docs/decisions/README.md and ARCHITECTURE.md list every decision file, nothing cites the retired
// design notes, and docs/ARCHITECTURE.md stays a page a newcomer reads in one sitting that names
// every module and only tests that exist. Reads the files, so a citation of a retired or renamed
// document fails here, not in a reader's hands.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <set>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

const fs::path kRoot = VOXTIER_SOURCE_DIR;

std::string slurp(const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

/// The repository's own text files: sources, shaders, scripts, build files, documents and scene
/// files, and CI's scripts (.ci/). Build trees, outputs and the bundled third-party models are
/// not the project's text; `withBundledModels` walks scenes/vox/ too (its MANIFEST.md is a
/// document others cite).
std::vector<fs::path> projectTextFiles(bool withBundledModels = false) {
    static const std::set<std::string> kExtensions = {
        ".cpp",  ".hpp", ".h",     ".comp", ".frag",     ".vert", ".md",   ".sh",    ".py",
        ".json", ".txt", ".cmake", ".in",   ".mustache", ".gp",   ".yaml", ".sbatch"};
    std::vector<fs::path> out;
    for (auto it = fs::recursive_directory_iterator(kRoot);
         it != fs::recursive_directory_iterator(); ++it) {
        const fs::path rel = fs::relative(it->path(), kRoot);
        const std::string first = rel.begin()->string();
        if (it->is_directory()) {
            const std::string name = it->path().filename().string();
            if ((name.rfind('.', 0) == 0 && name != ".ci") || first.rfind("build", 0) == 0 ||
                first == "out" || first == "voxtier-portable" || first == "fuzz-out" ||
                first == "gpu-check" || (rel == fs::path("scenes/vox") && !withBundledModels) ||
                rel == fs::path("tests/data"))
                it.disable_recursion_pending();
            continue;
        }
        if (kExtensions.count(it->path().extension().string()) ||
            it->path().filename() == "CMakeLists.txt" || first == ".ci")
            out.push_back(it->path());
    }
    return out;
}

std::string lineAt(const std::string& text, std::size_t pos) {
    return std::to_string(1 + std::count(text.begin(), text.begin() + long(pos), '\n'));
}

TEST(Docs, EveryCitedDocumentExists) {
    const std::vector<fs::path> files = projectTextFiles();
    ASSERT_GT(files.size(), 100u);
    // The Markdown documents the repository holds, by file name and by path.
    std::set<std::string> names;
    std::vector<std::string> paths;
    for (const fs::path& file : projectTextFiles(true))
        if (file.extension() == ".md") {
            names.insert(file.filename().string());
            paths.push_back("/" + fs::relative(file, kRoot).generic_string());
        }
    // What voxtier writes, not what it holds: the bench's and tools/gpu_check.sh's report.
    const std::set<std::string> outputs = {"report.md"};
    // A document name, possibly with a folder before it; not part of a web address.
    const std::regex cited(R"re(([A-Za-z0-9_./-]*/)?([A-Za-z0-9_-]+\.md)\b)re");
    int citations = 0;
    for (const fs::path& file : files) {
        const std::string text = slurp(file);
        for (auto m = std::sregex_iterator(text.begin(), text.end(), cited);
             m != std::sregex_iterator(); ++m) {
            const std::size_t pos = std::size_t(m->position(0));
            // The word the name ends: a web address names another site's document.
            const std::size_t word = text.find_last_of(" \t\n(<[`\"'", pos) + 1;
            if (text.substr(word, pos - word + 3).find("://") != std::string::npos) continue;
            ++citations;
            const std::string folder = (*m)[1], name = (*m)[2];
            if (outputs.count(name)) continue;
            const std::string where = fs::relative(file, kRoot).string() + ":" + lineAt(text, pos);
            if (folder.empty()) {
                EXPECT_TRUE(names.count(name)) << where << " cites " << name;
                continue;
            }
            // From the root, the citing file's folder or docs/, or the tail of a document's path
            // (an installed layout: "vox/MANIFEST.md" under share/voxtier/scenes/).
            const fs::path path = fs::path(folder) / name;
            const std::string tail = "/" + path.lexically_normal().generic_string();
            const bool exists =
                fs::exists(kRoot / path) || fs::exists(file.parent_path() / path) ||
                fs::exists(kRoot / "docs" / path) ||
                std::any_of(paths.begin(), paths.end(), [&](const std::string& p) {
                    return p.size() >= tail.size() &&
                           p.compare(p.size() - tail.size(), tail.size(), tail) == 0;
                });
            EXPECT_TRUE(exists) << where << " cites " << path.string();
        }
    }
    EXPECT_GT(citations, 50) << "the pattern found too few citations to mean anything";
}

/// Fails once per project text file in which `pattern` occurs, naming the file, the line, what
/// matched and `why`.
void expectNoFileMatches(const std::regex& pattern, const std::string& why) {
    for (const fs::path& file : projectTextFiles()) {
        const std::string text = slurp(file);
        std::smatch m;
        if (std::regex_search(text, m, pattern))
            ADD_FAILURE() << fs::relative(file, kRoot).string() << ":"
                          << lineAt(text, std::size_t(m.position(0))) << " cites \"" << m.str(0)
                          << "\": " << why;
    }
}

TEST(Docs, NoFileCitesTheSeedNotes) {
    // The notes were cited by number (the word seed and three digits) or by file name (three
    // digits and an underscore); a folder that happens to be called seeds (tools/fuzz.sh's
    // corpus) is not a citation.
    expectNoFileMatches(
        std::regex(R"re(\bseeds/[0-9]|\bseed 0[0-9][0-9]\b|\b00[0-9]_[A-Za-z]+\.md)re"),
        "the seed notes, which the repository does not hold");
}

TEST(Docs, ContractCitationsNameItsSections) {
    const std::string contract = slurp(kRoot / "docs" / "CONTRACT.md");
    ASSERT_FALSE(contract.empty());
    // Its sections ("## N. Title") and the numbered items of §3 ("N. **...").
    std::set<int> sections, items3;
    const std::regex heading(R"re(\n## ([0-9]+)\. )re");
    for (auto m = std::sregex_iterator(contract.begin(), contract.end(), heading);
         m != std::sregex_iterator(); ++m)
        sections.insert(std::stoi((*m)[1]));
    const std::size_t s3 = contract.find("\n## 3. "), s4 = contract.find("\n## 4. ");
    ASSERT_NE(s3, std::string::npos);
    ASSERT_NE(s4, std::string::npos);
    const std::string section3 = contract.substr(s3, s4 - s3);
    const std::regex item(R"re(\n([0-9]+)\. )re");
    for (auto m = std::sregex_iterator(section3.begin(), section3.end(), item);
         m != std::sregex_iterator(); ++m)
        items3.insert(std::stoi((*m)[1]));
    for (int n = 2; n <= 8; ++n) EXPECT_TRUE(sections.count(n)) << "CONTRACT.md has no §" << n;
    for (int n = 1; n <= 11; ++n) EXPECT_TRUE(items3.count(n)) << "CONTRACT.md has no §3." << n;

    const std::regex cited(R"re(CONTRACT\.md`? §([0-9]+)(\.([0-9]+))?)re");
    for (const fs::path& file : projectTextFiles()) {
        const std::string text = slurp(file);
        for (auto m = std::sregex_iterator(text.begin(), text.end(), cited);
             m != std::sregex_iterator(); ++m) {
            const std::string where = fs::relative(file, kRoot).string() + ":" +
                                      lineAt(text, std::size_t(m->position(0)));
            const int n = std::stoi((*m)[1]);
            EXPECT_TRUE(sections.count(n)) << where << " cites CONTRACT.md §" << n;
            if ((*m)[3].matched) {
                EXPECT_TRUE(n == 3 && items3.count(std::stoi((*m)[3])))
                    << where << " cites CONTRACT.md §" << n << "." << (*m)[3];
            }
        }
    }
}

TEST(Docs, DecisionIndexAndArchitectureListEveryDecision) {
    const std::string index = slurp(kRoot / "docs" / "decisions" / "README.md");
    const std::string architecture = slurp(kRoot / "docs" / "ARCHITECTURE.md");
    ASSERT_FALSE(index.empty());
    ASSERT_FALSE(architecture.empty());
    int decisions = 0;
    for (const auto& e : fs::directory_iterator(kRoot / "docs" / "decisions")) {
        const std::string name = e.path().filename().string();
        if (e.path().extension() != ".md" || name == "README.md") continue;
        ++decisions;
        EXPECT_NE(index.find("(" + name + ")"), std::string::npos)
            << "docs/decisions/README.md does not list " << name;
        EXPECT_NE(architecture.find("(decisions/" + name + ")"), std::string::npos)
            << "docs/ARCHITECTURE.md does not link " << name;
    }
    EXPECT_GT(decisions, 0);
}

TEST(Docs, NoFileCitesTheRetiredDesignNotes) {
    // The notebook's rules are CONTRACT.md, its map ARCHITECTURE.md, its figures decisions/; a
    // citation by section alone escapes the file-name check above.
    expectNoFileMatches(std::regex(R"re(\bDESIGN(\.md| §))re"),
                        "retired: cite CONTRACT.md, ARCHITECTURE.md or docs/decisions/");
}

TEST(Docs, ArchitectureNamesEveryModuleFolder) {
    const std::string text = slurp(kRoot / "docs" / "ARCHITECTURE.md");
    ASSERT_FALSE(text.empty());
    int modules = 0;
    for (const auto& e : fs::directory_iterator(kRoot)) {
        if (!e.is_directory() || !fs::exists(e.path() / "CMakeLists.txt")) continue;
        const std::string name = e.path().filename().string();
        if (name.rfind("build", 0) == 0) continue;
        ++modules;
        EXPECT_NE(text.find("`" + name + "/`"), std::string::npos)
            << "docs/ARCHITECTURE.md does not describe the folder " << name << "/";
    }
    EXPECT_GE(modules, 8);
}

TEST(Docs, ArchitectureNamesOnlyTestsAndFuzzersThatExist) {
    // "Where to change what" sends a reader to tests by name; a renamed test must not leave a
    // dead name there.
    const std::string text = slurp(kRoot / "docs" / "ARCHITECTURE.md");
    ASSERT_FALSE(text.empty());
    // A name after "*" is a family ("reference_*_test"), not a file.
    const std::regex named(R"re((\*)?\b(fuzz/)?([a-z0-9_]+_(test|fuzz))\b)re");
    int names = 0;
    for (auto m = std::sregex_iterator(text.begin(), text.end(), named);
         m != std::sregex_iterator(); ++m) {
        if ((*m)[1].matched) continue;
        ++names;
        const std::string name = (*m)[3];
        const fs::path file = kRoot / ((*m)[4] == "fuzz" ? "fuzz" : "tests") / (name + ".cpp");
        EXPECT_TRUE(fs::exists(file))
            << "docs/ARCHITECTURE.md:" << lineAt(text, std::size_t(m->position(0))) << " names "
            << name << ", which has no " << file.filename();
    }
    EXPECT_GT(names, 20);
}

TEST(Docs, ArchitectureIsAPageOfAtMost250Lines) {
    const std::string text = slurp(kRoot / "docs" / "ARCHITECTURE.md");
    ASSERT_FALSE(text.empty());
    EXPECT_LE(std::count(text.begin(), text.end(), '\n'), 250);
}

} // namespace

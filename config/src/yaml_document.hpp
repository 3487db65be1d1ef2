// Reading a config or a PLC script as the one YAML document it must be. YAML::Load reads the
// first document of a stream and ignores the rest: a file with `---` and a second document, or
// anything at all after `...`, was accepted with that part silently left out.
#pragma once

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/exceptions.h>
#include <yaml-cpp/mark.h>
#include <yaml-cpp/parser.h>
#include <yaml-cpp/yaml.h>

#include <sstream>
#include <string>

namespace tgm {

//! The message (after "FILE:LINE:COLUMN: YAML syntax: ") for a second document.
inline constexpr const char* kSecondYamlDocument =
    "a second YAML document starts here; the file must hold one";

namespace detail {

// Counts the documents of a stream without building them, and stops at the start of the
// second: its content is not parsed, so a second document that is not YAML at all is named as
// a second document rather than by the first syntax error in it. yaml-cpp also starts one
// without `---` where a top-level value ends and more text follows ("- a" then "b: 1").
class SecondDocumentFinder : public YAML::EventHandler {
 public:
  //! The first document was read to its end: what is thrown from here on is about the text
  //! after it.
  bool first_ended() const { return first_ended_; }

  void OnDocumentStart(const YAML::Mark& mark) override {
    if (++documents_ > 1) throw YAML::ParserException(mark, kSecondYamlDocument);
  }
  void OnDocumentEnd() override { first_ended_ = true; }
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t,
                const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                       YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t,
                  YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}

 private:
  int documents_ = 0;
  bool first_ended_ = false;
};

}  // namespace detail

//! The one YAML document of `text` (a null node when it has none: an empty file or only
//! comments). Throws what YAML::Load throws, and a YAML::ParserException marked where a second
//! document starts (kSecondYamlDocument). Comments and `...` after the document are fine.
inline YAML::Node load_one_document(const std::string& text) {
  // First a pass over the events, which builds nothing (aliases are not expanded): yaml-cpp
  // has no public way to build a node from a parser that could then be asked for more.
  {
    std::istringstream in(text);
    YAML::Parser parser(in);
    detail::SecondDocumentFinder finder;
    try {
      while (parser.HandleNextDocument(finder)) {
      }
    } catch (const YAML::Exception& e) {
      // The scanner reads the first token after the document before the second document
      // starts, and throws when that is not YAML ("}}}" after `...`): text after the document
      // all the same, said as such.
      if (!finder.first_ended()) throw;
      throw YAML::ParserException(e.mark, kSecondYamlDocument);
    }
  }
  return YAML::Load(text);
}

}  // namespace tgm

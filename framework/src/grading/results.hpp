// The grader's outputs: Gradescope's results.json, JUnit XML and summary.txt. Every string
// in them is sanitized (valid UTF-8, no control characters), and every file is written
// atomically (a temporary file, flushed, then renamed), so a reader sees either the old
// file or the whole new one.
#pragma once

#include <cstddef>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

namespace pinsim::grading {

/// Writes `text` to `file` atomically; throws std::runtime_error naming the file on failure.
void write_atomically(const std::filesystem::path& file, const std::string& text);

/// JUnit XML for a Gradescope results object.
std::string junit_xml(const nlohmann::json& results, const std::string& suite);

/// The readable summary: score, then one line per test, failed tests with their output.
/// With `with_outputs` false, only the score line and one line per test: results.json's
/// top-level output, which must not repeat what every test already shows.
std::string summary_text(const nlohmann::json& results, const std::string& rubric_name,
                         bool with_outputs = true);

/// The pictures of failed simulation and path tests: each PNG at most kPictureMaxBytes of
/// base64 text (a larger one is left out), all of one results object at most
/// kPicturesMaxBytes together (a picture beyond is left out, and its test's text says so).
inline constexpr std::size_t kPictureMaxBytes = 48 * 1024;
inline constexpr std::size_t kPicturesMaxBytes = 256 * 1024;

/// results.json as Gradescope reads it. A test of `results` may carry "picture"
/// ({"png_base64", "width", "height", "caption", "at"}: a PNG and its caption, to be shown
/// after the first `at` bytes of its text "output"); such a test becomes "output_format":
/// "html", its text in <pre> blocks with the picture and caption between them, and the key
/// "picture" is dropped. junit.xml and summary.txt show the text alone.
nlohmann::json gradescope_results(const nlohmann::json& results);

/// Writes results.json, junit.xml and summary.txt into `dir`, atomically each.
void write_results(const std::filesystem::path& dir, const nlohmann::json& results,
                   const std::string& rubric_name);

/// A results object with score 0 out of `max_score` (the rubric's total, so a course sees
/// 0 / N rather than 0 / 0) and `reason` as its output: for the grader's own failures.
nlohmann::json failed_results(const std::string& reason, double max_score = 0.0);

/// results.json's extra_data: {"sandbox": {"mode": "bubblewrap"|"fallback"|"none",
/// "detail": one line}}, what isolated the submission's code.
nlohmann::json sandbox_extra_data();

}  // namespace pinsim::grading

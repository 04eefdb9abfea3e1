// The "contacts" block's one parser (contact_options.hpp), used by the sdf and box2d
// backends: values, defaults, and errors naming the file and JSON path.
#include <catch2/catch.hpp>

#include "contact_options.hpp"

using namespace pinsim;
using namespace pinsim::sdf;
using nlohmann::json;

namespace {

/// read_contacts on a scene with `scene` as its backend document.
ContactOptions read(const json& scene) {
  pinsim_state_view sv{0, 0.0, nullptr, nullptr, nullptr, nullptr};
  const CreateContext ctx{Params(json::object()), scene, StateView(sv), Elements{}, "s.json"};
  return read_contacts(ctx);
}

/// The message read_contacts throws for `contacts`, or "no error".
std::string error_of(const json& contacts) {
  try {
    read({{"obstacles", json::array()}, {"contacts", contacts}});
  } catch (const std::exception& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST_CASE("contacts: absent or null gives the defaults, values are read") {
  for (const json& scene : {json{{"obstacles", json::array()}},
                            json{{"obstacles", json::array()}, {"contacts", nullptr}}}) {
    const ContactOptions c = read(scene);
    CHECK(!c.particles);
    CHECK(c.restitution == 1.0);
  }
  const ContactOptions c = read({{"contacts", {{"particles", true}, {"restitution", 0.25}}}});
  CHECK(c.particles);
  CHECK(c.restitution == 0.25);
  CHECK(read({{"contacts", {{"restitution", 0}}}}).restitution == 0.0);
  CHECK(read({{"contacts", {{"restitution", 1}}}}).restitution == 1.0);
}

TEST_CASE("contacts: each bad value is an error naming the file, the path and what was expected") {
  CHECK(error_of(json::array({1})) == "s.json: contacts: expected an object, got [1]");
  CHECK(error_of({{"particle", true}}) ==
        "s.json: contacts.particle: unknown key (expected one of: particles, restitution)");
  CHECK(error_of({{"particles", 1}}) ==
        "s.json: contacts.particles: expected true or false, got 1");
  CHECK(error_of({{"restitution", "high"}}) ==
        "s.json: contacts.restitution: expected a number, got \"high\"");
  CHECK(error_of({{"restitution", 1.5}}) ==
        "s.json: contacts.restitution: must be in [0, 1], got 1.5");
  CHECK(error_of({{"restitution", -0.1}}) ==
        "s.json: contacts.restitution: must be in [0, 1], got -0.1");
}

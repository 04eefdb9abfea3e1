// The correct student spring as a plugin (the class is in student_spring.hpp, which the
// grader's hostile fixtures reuse).
#include "student_spring.hpp"

PINSIM_PLUGIN(StudentSpring)

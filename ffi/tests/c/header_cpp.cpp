// The header compiles as C++11 (g++ -std=c++11 -Wall -Wextra -Wpedantic -Werror).
#include "reactionless.h"

static_assert(sizeof(rl_plan) >= RL_ETA_LEN * sizeof(double), "rl_plan holds eta");

int main() {
    rl_plan plan = {};
    return rl_planner_step(nullptr, 1, &plan) == RL_E_NULL ? 0 : 1;
}

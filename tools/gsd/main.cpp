// Temporary entry point while the CLI is assembled.
#include <gsd/core.hpp>
#include <cstdio>
int main() { std::printf("gsd %s\n", std::string(gsd::version()).c_str()); return 0; }

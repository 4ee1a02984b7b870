#include <CLI/CLI.hpp>
#include <cstdio>
int main(int argc, char** argv) { CLI::App app{"pumeta"}; CLI11_PARSE(app, argc, argv); return 0; }

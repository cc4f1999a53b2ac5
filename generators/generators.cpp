#include "generators/generators.hpp"

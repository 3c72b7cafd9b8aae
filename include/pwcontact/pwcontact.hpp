// pwcontact: the Perram-Wertheim contact function of two ellipsoids, for one
// pair (reference path) and for very many pairs at once (batch path).
#pragma once

#include "pwcontact/batch.hpp"
#include "pwcontact/ellipsoid.hpp"
#include "pwcontact/monte_carlo.hpp"
#include "pwcontact/moving_scene.hpp"
#include "pwcontact/neighbor_list.hpp"
#include "pwcontact/reference.hpp"
#include "pwcontact/scene_files.hpp"
#include "pwcontact/screen.hpp"
#include "pwcontact/status.hpp"

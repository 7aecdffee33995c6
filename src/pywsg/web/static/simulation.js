"use strict"; // Simulation: the forms are wired by common.js.

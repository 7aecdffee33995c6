"use strict"; // Help: static content; the live box is wired by common.js.

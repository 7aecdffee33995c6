// The 404 page: nothing of its own (common.js gives the menu and the Gripper box).

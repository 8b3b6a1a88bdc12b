# Loads images with Godot's Image class and prints every texel, one line
# each: "KIND x y r g b a". Run headless with Godot 3:
#   godot3-server --no-window -s docs/engine-check/dump.gd -- exr FILE.exr png FILE.png
# EXR texels are printed as the floats Godot holds, PNG texels as 8-bit
# codes (Godot's Color times 255, rounded). A file Godot cannot load prints
# "KIND error CODE" and nothing else for it.
extends SceneTree

func _init():
	var args = OS.get_cmdline_args()
	var i = 0
	while i + 1 < args.size():
		var kind = args[i]
		if kind != "exr" and kind != "png":
			i += 1
			continue
		var path = args[i + 1]
		i += 2
		var img = Image.new()
		var err = img.load(path)
		if err != OK:
			print("%s error %d" % [kind, err])
			continue
		print("%s format %d size %d %d" % [kind, img.get_format(), img.get_width(), img.get_height()])
		img.lock()
		for y in range(img.get_height()):
			for x in range(img.get_width()):
				var c = img.get_pixel(x, y)
				if kind == "exr":
					print("exr %d %d %.9f %.9f %.9f %.9f" % [x, y, c.r, c.g, c.b, c.a])
				else:
					print("png %d %d %d %d %d %d" % [x, y, round(c.r * 255), round(c.g * 255), round(c.b * 255), round(c.a * 255)])
		img.unlock()
	quit()
